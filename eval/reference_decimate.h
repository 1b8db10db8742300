// In-core baseline simplifier: OpenMesh's quadric-error decimation, what the paper calls "QSlim".
#pragma once
#include "vdb_isosimp/mesh.h"

#include <cstddef>

namespace vdb_isosimp::eval {

// Decimates `full` to targetFaces faces (OpenMesh stops at the first collapse that reaches
// <= targetFaces, so a closed mesh ends at targetFaces or targetFaces - 1; fewer if no legal
// collapse is left). DecimaterT with ModQuadricT as the priority module (default settings:
// area-weighted face quadrics, collapse to the surviving vertex, no error bound) and
// ModNormalFlippingT as a binary module (default: rejects collapses that turn any face normal by
// more than 90 degrees, i.e. fold-overs), so the baseline does not win by producing flipped faces.
// Faces OpenMesh refuses to load (complex edges/vertices, see toOpenMesh) are left out: their
// number goes to *refusedFaces if given; if refusedFaces is null and any face is refused, throws
// std::runtime_error. Returns the garbage-collected result (unreferenced input points stay).
Mesh decimateWithOpenMesh(const Mesh& full, size_t targetFaces, size_t* refusedFaces = nullptr);

} // namespace vdb_isosimp::eval

// Internal header of the evaluation library: the OpenMesh mesh type and converters between it and
// vdb_isosimp::Mesh. Kept apart from mesh_io.h so that only code that really needs OpenMesh pulls
// in its (large) headers.
#pragma once
#include "vdb_isosimp/mesh.h"

// MeshIO must come before the mesh kernel headers: it registers the readers and writers.
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include <cstddef>

namespace vdb_isosimp::eval {

// Default traits: float positions, like vdb_isosimp::Mesh, so conversions are exact.
using TriMesh = OpenMesh::TriMesh_ArrayKernelT<>;

// Copies all points (also unreferenced ones, same order) and adds the triangles in order.
// OpenMesh's half-edge structure cannot hold every index array: add_face refuses faces that would
// create a complex edge (an edge with more than two faces, or two faces traversing it in the same
// direction) or a complex vertex; faces with repeated or out-of-range indices are refused here
// before reaching OpenMesh. Refused faces are skipped and their number is stored in refusedFaces.
TriMesh toOpenMesh(const Mesh& mesh, size_t& refusedFaces);

// Same, but throws std::runtime_error (with the count) if any face is refused.
TriMesh toOpenMesh(const Mesh& mesh);

// Copies the non-deleted vertices and faces (in handle order, so a garbage-collected mesh maps
// one-to-one). Works whether or not the mesh has status attributes.
Mesh fromOpenMesh(const TriMesh& mesh);

} // namespace vdb_isosimp::eval

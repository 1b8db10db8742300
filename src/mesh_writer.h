// Mesh writer: binary little-endian PLY (float x y z, uchar-count int vertex_indices), written to a
// temporary file beside the target and renamed only on success, so a failed or interrupted write never
// leaves a truncated mesh under the output name.
#pragma once
#include <string>

#include "mesh.h"

namespace vdb_isosimp {

// Writes `mesh` to `path`; `comment` lines go into the header. @throw OutputError naming the file.
void writeMesh(const Mesh& mesh, const std::string& path, const std::string& comment = {});

} // namespace vdb_isosimp

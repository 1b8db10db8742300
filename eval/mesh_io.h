// Mesh file input for the evaluation programs, through OpenMesh's readers (PLY binary/ascii, OBJ,
// STL binary/ascii, OFF). Deliberately free of OpenMesh types: the OpenMesh <-> Mesh converters
// live in eval_openmesh.h.
#pragma once
#include "vdb_isosimp/mesh.h"

#include <string>

namespace vdb_isosimp::eval {

// Reads a triangle mesh. The file's vertex and face arrays are kept exactly as stored (order,
// unreferenced vertices, non-manifold and misoriented faces included) because OpenMesh's readers
// feed a plain index-array importer here, not a half-edge mesh; so mesh_stats sees the file's real
// topology. Polygons with more than three corners are split into a triangle fan.
// STL stores no indices: OpenMesh's STL reader merges corners with identical positions.
// Throws std::runtime_error with a one-line message naming the file when it does not exist, has an
// unsupported extension, cannot be parsed, or references a vertex index out of range.
Mesh readMesh(const std::string& path);

// Writes the mesh with OpenMesh's writers; the format follows the extension (.ply, .obj, .stl,
// .off). PLY and STL are written binary (exact floats), OBJ and OFF as text with 9 significant
// digits (also exact for floats). Goes through an OpenMesh half-edge mesh, so it throws
// std::runtime_error if OpenMesh refuses any face (complex edge/vertex) rather than silently write
// fewer faces. For tests and benchmarks; the pipeline has its own streaming writer.
void writeMeshOpenMesh(const Mesh& mesh, const std::string& path);

} // namespace vdb_isosimp::eval

// Mesh writer: the format follows the output extension.
//   .ply  binary little-endian PLY (default) or ASCII PLY (WriteOptions::ascii)
//   .obj  Wavefront OBJ (text)
//   .stl  binary STL (no indices: readers weld corners by position)
//   .glb  glTF 2.0 binary (one node and one mesh, named after the grid)
// Positions are world space as given by the grid's transform, in the world units of that transform;
// the formats with room for it say so in their header (PLY comment, OBJ comment, STL header, glTF
// asset.extras). glTF itself defines its unit as the metre, so a grid in metres (Houdini's and
// Blender's default) lands at its true size. Everything goes to a temporary file beside the target
// that is renamed only on success, so a failed or interrupted write never leaves a truncated mesh
// under the output name.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "mesh.h"

namespace vdb_isosimp {

enum class MeshFormat { PlyBinary, PlyAscii, Obj, StlBinary, Glb };

struct WriteOptions {
    bool ascii = false;         // .ply only: ASCII instead of binary
    bool normals = false;       // area-weighted vertex normals (PLY nx/ny/nz, OBJ vn, glTF NORMAL);
                                // STL always carries its per-face normals
    std::string objectName;     // the grid name: OBJ `o`, glTF node/mesh name, PLY obj_info, STL header
    std::string comment;        // one free line (PLY comment, OBJ comment, glTF asset.extras.comment)
};

// Format for `path` by its extension (case-insensitive). @throw OutputError naming the file for an
// unsupported extension, or for `ascii` with anything but .ply.
MeshFormat formatForPath(const std::string& path, bool ascii = false);

// Whether the format carries Mesh::attributes: PLY as vertex properties named after the attribute
// (a vector: NAME_x NAME_y NAME_z), glTF as custom attributes `_NAME` (SCALAR or VEC3 float). OBJ and
// STL have no room for them.
bool formatHoldsAttributes(MeshFormat format);

// Writes `mesh` to `path`. @throw OutputError naming the file (also for an index out of range or a
// non-finite position, or attributes the format cannot hold, before anything is created).
void writeMesh(const Mesh& mesh, const std::string& path, const WriteOptions& options);
// Same, binary PLY / by extension, with `comment` as the only option.
void writeMesh(const Mesh& mesh, const std::string& path, const std::string& comment = {});

// Area-weighted vertex normals: the sum of the (unnormalised) normals of the faces around each vertex,
// normalised; (0, 0, 1) where that sum is zero (unreferenced vertex, zero-area fan).
std::vector<std::array<float, 3>> vertexNormals(const Mesh& mesh);

} // namespace vdb_isosimp

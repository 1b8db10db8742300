// Hard-surface and exact-iso test volumes, built with OpenVDB's own tools the way Houdini and Blender
// pipelines build them: level-set boxes and Platonic solids, CSG of boxes and a polygonal cylinder,
// a fog box from a constant tile, integer-valued CT-like data. Used by make_volume, the test suite and
// benchmarks/fidelity.sh, so every fidelity claim is measured on the same volumes.
#pragma once
#include <openvdb/openvdb.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace vdb_isosimp::volumes {

struct TestVolume {
    openvdb::FloatGrid::Ptr grid;
    double iso = 0.0;
};

// Names accepted by makeVolume(): box cube tetrahedron octahedron dodecahedron icosahedron csg fog-box
// ct-int. Each hard surface fits a cube of about `size` voxels; the level sets' zero crossing lies on
// voxel planes for `box` (a bounding box on integer coordinates), in general position for the rest.
// `ct-int` is fractal noise quantised to integers in [0, 255] with the iso-value 100 on an integer, so
// many voxels lie exactly at the iso-value.
const std::vector<std::string>& volumeNames();

// Hard surfaces only (every name but ct-int).
const std::vector<std::string>& hardSurfaceNames();

// `rotated`: the grid's transform is a rotation about a skew axis times an anisotropic scale
// (1, 0.7, 1.3) plus a translation; the surface is then a sheared, rotated copy of the solid, still
// made of flat faces and sharp edges. Throws std::invalid_argument for an unknown name.
TestVolume makeVolume(const std::string& name, int size, bool rotated = false);

// CT-like fractal value noise at voxel (x, y, z) of a size^3 volume: 4 octaves from a 12-voxel period,
// minus 0.3, faded to exactly 0 within 10 voxels of the border so constant regions become tiles.
double fractalNoise(int x, int y, int z, int size, uint64_t seed);

// A fog of `value(x, y, z)` on a size^3 grid of `voxel` world units: zero voxels left inactive, constant
// regions pruned to tiles.
openvdb::FloatGrid::Ptr fog(int size, double voxel, const std::function<double(int, int, int)>& value);

// The fog of make_volume's `noise`: fractalNoise (iso-value 0.3 in the noise's own units: many components).
openvdb::FloatGrid::Ptr noiseFog(int size, uint64_t seed, double voxel = 1.0);

} // namespace vdb_isosimp::volumes

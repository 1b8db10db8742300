// Small hand-built and random sparse grids for the tests, and a plain dense Marching Cubes reference.
#pragma once
#include "core/marching_cubes.h"
#include "vdb_isosimp/mesh.h"

#include <openvdb/openvdb.h>

#include <string>

namespace vdb_isosimp::testing {

struct GridSpec {
    unsigned seed = 1;
    bool levelSet = true;
    bool anisotropic = true;   // non-unit scale per axis, rotation and translation
    bool mirrored = false;     // negative determinant
    bool bigTile = false;      // one 128^3 tile (upper internal node level)
    bool exactIso = true;      // some voxels exactly at the iso-value
};

// A random sparse grid: scattered and adjacent leaves, 8^3 tiles on both sides of the iso-value,
// optionally a 128^3 tile, all values finite.
openvdb::FloatGrid::Ptr randomSparseGrid(const GridSpec& spec);

// Writes a grid to a .vdb file in the test temp folder and returns the path.
std::string writeGrid(openvdb::GridBase::Ptr grid, const std::string& name);

// Plain dense triple-loop Marching Cubes over a dense copy of every value that matters (the grid's
// bounding box plus one voxel): the reference the streaming pipeline must reproduce at R = 1.
Mesh denseMarchingCubes(const openvdb::FloatGrid& grid, double iso);

} // namespace vdb_isosimp::testing

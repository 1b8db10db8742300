// Marching Cubes: the case table and the extraction of one 8^3 block of cells.
//
// The table is generated, not typed in: on every cube face the crossing points are paired so that
// inside corners are never joined across the face (the face's own corner values decide, so the two
// cells sharing a face always agree and the surface has no cracks). The paired segments form closed
// loops on the cube's surface; each loop is fanned into triangles wound counter-clockwise seen from
// outside the inside region.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "core/edge_key.h"

namespace vdb_isosimp {

// Corner c of a cell sits at offset (c&1, (c>>1)&1, (c>>2)&1) from the cell's min corner.
// Edge e runs along axis a = e/4 from corner edgeCorner(e,0) to edgeCorner(e,1) (the +a neighbour);
// its two other coordinates are the bits of e%4 (lower axis first). Edges 0, 4 and 8 start at corner 0:
// they are the cell's "min-corner edges" that modifiability is about.
struct CubeGeometry {
    static int edgeAxis(int e) { return e / 4; }
    static int edgeCorner(int e, int end);
};

// Triangles of one case as triples of cell edges; at most 12 edge points, so at most 10 triangles.
struct McCase {
    uint8_t triangleCount = 0;
    std::array<std::array<uint8_t, 3>, 12> triangles{};
};

// The 256-entry table; case bit c is set when corner c is inside.
const std::array<McCase, 256>& mcTable();

// The surface of one block: local vertices (one per crossing edge, welded inside the block), their
// global edge keys and world positions, triangles over local vertices, and whether each vertex is final
// once this block is integrated (see modifiability.h).
struct BlockMesh {
    uint64_t blockIndex = 0;
    double minValue = 0.0, maxValue = 0.0;  // range of the block's samples, for "no surface" messages
    std::vector<EdgeKey> keys;
    std::vector<std::array<double, 3>> positions;
    std::vector<uint8_t> finalAfterBlock;
    std::vector<std::array<uint32_t, 3>> triangles;
    // An attribute's value at each position, when the decimator weighs one (Options::attributeWeight);
    // empty otherwise.
    std::vector<double> attribute;
};

// The 9^3 corner samples of a block (its 8^3 cells plus the +x/+y/+z layer), x fastest.
struct BlockSamples {
    static constexpr int N = 9;
    std::array<int32_t, 3> origin{};
    std::array<double, N * N * N> values{};
    double& at(int x, int y, int z) { return values[(z * N + y) * N + x]; }
    double at(int x, int y, int z) const { return values[(z * N + y) * N + x]; }
};

// How corner values are classified and placed.
struct Classifier {
    double iso = 0.0;
    bool insideBelow = true;  // level sets: inside is value < iso; fog: inside is value > iso
    bool inside(double v) const { return insideBelow ? v < iso : v > iso; }
};

// Index-space to world-space map (the grid's linear transform) as a row-major 3x4 matrix.
struct Affine {
    std::array<double, 12> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    std::array<double, 3> apply(const std::array<double, 3>& p) const;
    double determinant() const;
};

// Case index of every cell of the block, cell (x,y,z) at (z * 8 + y) * 8 + x: bit k set when corner
// (k & 1, k >> 1 & 1, k >> 2 & 1) is inside. Each of the 9^3 samples is classified once (up to eight
// cells share it).
std::array<uint8_t, 512> blockCases(const BlockSamples& s, const Classifier& c);

// Number of triangles the block yields (the exact counting pass for --faces).
uint64_t countBlockTriangles(const BlockSamples& s, const Classifier& c);

// Extracts the block's surface. `flipWinding` compensates a mirroring transform.
void extractBlock(const BlockSamples& s, const Classifier& c, const Affine& toWorld, bool flipWinding,
                  BlockMesh& out);

} // namespace vdb_isosimp

// Block order: which 8^3 blocks of cells to extract, and in what order.
//
// Every cell whose 8 corner values straddle the iso-value must be extracted exactly once. A straddling
// cell either touches a leaf voxel, so it lies in that leaf's block or in one of the 7 blocks below /
// behind / left of it (their +x/+y/+z corners sample the leaf), or all its corners hold constant tile or
// background values. In that case two corners joined by a cell edge differ in sign and lie in different
// constant regions, so the edge crosses a face of a tile: the cell lies in the one-block shell along
// that face, and the region across the face is a tile at least as large or background (finer structure
// across is covered by the finer tiles' own faces and by the leaves). Blocks are returned sorted by
// (z, y, x) of their origin, without duplicates: the order modifiability.h relies on.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "core/marching_cubes.h"

namespace vdb_isosimp {

using BlockOrigin = std::array<int32_t, 3>;

// The leaves the 9^3 samples of block o read, d = 0..7: its own (d = 0) and those at its +x/+y/+z sides,
// o + 8 (d & 1, d >> 1 & 1, d >> 2 & 1). Bit d of a mask over a block's leaves (Volume::sample) names this one.
inline BlockOrigin sampledLeaf(const BlockOrigin& o, int d)
{
    return {o[0] + 8 * (d & 1), o[1] + 8 * ((d >> 1) & 1), o[2] + 8 * ((d >> 2) & 1)};
}

// The other way: block d (0..7) of those that sample the leaf at `leaf`, the leaf's own block for d = 0
// (sampledLeaf(samplingBlock(leaf, d), d) == leaf).
inline BlockOrigin samplingBlock(const BlockOrigin& leaf, int d)
{
    return {leaf[0] - 8 * (d & 1), leaf[1] - 8 * ((d >> 1) & 1), leaf[2] - 8 * ((d >> 2) & 1)};
}

// Block origins compared on `axis` first, then on the others in z, y, x order: a lexicographic order, so
// a block never comes after one componentwise above it. Axis 2 is the z/y/x order of sortBlocks.
inline bool lexBefore(const BlockOrigin& a, const BlockOrigin& b, int axis)
{
    if (a[axis] != b[axis]) return a[axis] < b[axis];
    for (int k = 2; k >= 0; --k)
        if (k != axis && a[k] != b[k]) return a[k] < b[k];
    return false;
}

// Sorts block origins (multiples of 8, as every listed block is) by (z, y, x) and removes duplicates.
void sortBlocks(std::vector<BlockOrigin>& blocks);

// What a tree read in part says of the lower internal nodes it does not hold (a distributed run's rank
// reads the topology of its own share of them: Volume::open): whether (x, y, z) lies in one (false:
// the tree holds what is there), and if so whether a leaf is there (`leaf`) or else the tile value. The
// tree itself holds an inactive background tile in such a node's place. Empty: the tree is whole.
using AbsentLowerProbe = std::function<bool(const std::array<int32_t, 3>& xyz, bool& leaf, double& value)>;

// Collects the blocks of an OpenVDB tree (float or double), sorted and without duplicates. Part `part`
// of `parts` collects those of that share of the leaves and of the tiles' faces: the parts' lists
// merged (mergeBlockRuns) are the whole list, as the ranks of a distributed run divide it. @throw
// InputError for non-finite tiles (every part checks every tile) or coordinates outside the range
// vertex keys can name (each part checks its leaves).
// A tree read in part (`absent`) lists the blocks of its own leaves and tiles (and of the upper nodes'
// tiles, which every part holds): each part's list merged is again the whole list.
template <typename TreeT>
std::vector<BlockOrigin> collectBlocks(const TreeT& tree, const Classifier& c, size_t part = 0, size_t parts = 1,
                                       const AbsentLowerProbe& absent = {});

// Merges consecutive runs of `blocks`, each sorted by (z, y, x) without duplicates and ending at
// runEnds[i], into one such list (a block listed by two runs stays once).
void mergeBlockRuns(std::vector<BlockOrigin>& blocks, const std::vector<size_t>& runEnds);

// How many blocks the tiles' faces add to collectBlocks (before duplicates go), without collecting
// them: a few tiles can describe a surface of millions of blocks, which the memory estimate must see
// before they are listed. @throw InputError as collectBlocks does.
template <typename TreeT>
uint64_t countTileShellBlocks(const TreeT& tree, const Classifier& c, const AbsentLowerProbe& absent = {});

} // namespace vdb_isosimp

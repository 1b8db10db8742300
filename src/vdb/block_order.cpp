#include "vdb/block_order.h"

#include "core/edge_key.h"
#include "vdb_isosimp/errors.h"

#include <openvdb/openvdb.h>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace vdb_isosimp {

namespace {

// Sorts block origins (multiples of 8) by (z, y, x) without duplicates through one bit per place of
// their bounding box, set and then read in order: two passes instead of a sort's log n. Only where the
// bits take no more room than the list (a place per 96 bits of it); false, untouched, otherwise.
bool sortBlocksInBox(std::vector<BlockOrigin>& blocks)
{
    if (blocks.empty()) return true;
    BlockOrigin lo = blocks[0], hi = blocks[0];
    for (const BlockOrigin& b : blocks)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], b[a]);
            hi[a] = std::max(hi[a], b[a]);
        }
    uint64_t size[3];
    for (int a = 0; a < 3; ++a) size[a] = uint64_t(int64_t(hi[a]) - lo[a]) / 8 + 1;
    const uint64_t limit = uint64_t(blocks.size()) * 96;
    if (size[0] > limit || size[1] > limit / size[0] || size[2] > limit / (size[0] * size[1])) return false;
    std::vector<uint64_t> bits((size[0] * size[1] * size[2] + 63) / 64, 0);
    for (const BlockOrigin& b : blocks) {
        const uint64_t i = ((uint64_t(b[2] - lo[2]) / 8 * size[1]) + uint64_t(b[1] - lo[1]) / 8) * size[0] + uint64_t(b[0] - lo[0]) / 8;
        bits[i / 64] |= uint64_t(1) << (i % 64);
    }
    // The places come in increasing order: x, y and z follow by carries, not divisions.
    size_t n = 0;
    uint64_t at = 0, x = 0, y = 0, z = 0;
    for (size_t w = 0; w < bits.size(); ++w)
        for (uint64_t word = bits[w]; word; word &= word - 1) {
            const uint64_t i = w * 64 + uint64_t(__builtin_ctzll(word));
            x += i - at;
            at = i;
            for (; x >= size[0]; x -= size[0])
                if (++y == size[1]) {
                    y = 0;
                    ++z;
                }
            blocks[n++] = {lo[0] + int32_t(8 * x), lo[1] + int32_t(8 * y), lo[2] + int32_t(8 * z)};
        }
    blocks.resize(n);
    return true;
}

// Gives back the room of duplicates where they took more than an eighth of the list (collection
// pushes a block once per leaf or tile face that needs it, and that room would otherwise stay reserved
// all run long). Less is kept: the copy would touch every page of a fresh array, a page fault each.
void releaseDuplicatesRoom(std::vector<BlockOrigin>& blocks)
{
    if (blocks.capacity() - blocks.size() > blocks.size() / 8) blocks.shrink_to_fit();
}

} // namespace

void sortBlocks(std::vector<BlockOrigin>& blocks)
{
    // A total order: the sorted list is the same on any number of threads.
    if (!sortBlocksInBox(blocks)) {
        tbb::parallel_sort(blocks.begin(), blocks.end(), [](const BlockOrigin& a, const BlockOrigin& b) { return lexBefore(a, b, 2); });
        blocks.erase(std::unique(blocks.begin(), blocks.end()), blocks.end());
    }
    releaseDuplicatesRoom(blocks);
}

void mergeBlockRuns(std::vector<BlockOrigin>& blocks, const std::vector<size_t>& runEnds)
{
    if (sortBlocksInBox(blocks)) {
        releaseDuplicatesRoom(blocks);
        return;
    }
    // Neighbouring runs merge pairwise, round after round, the pairs of a round on all threads: a
    // round reads every block once, and W runs take ceil(log2 W) rounds.
    const auto less = [](const BlockOrigin& a, const BlockOrigin& b) { return lexBefore(a, b, 2); };
    std::vector<size_t> ends = runEnds;
    std::vector<BlockOrigin> merged(blocks.size());
    while (ends.size() > 1) {
        std::vector<size_t> next((ends.size() + 1) / 2);
        tbb::parallel_for(size_t(0), next.size(), [&](size_t k) {
            const size_t begin = 2 * k == 0 ? 0 : ends[2 * k - 1], mid = ends[2 * k];
            const size_t end = 2 * k + 1 < ends.size() ? ends[2 * k + 1] : mid;
            const auto at = [](auto& v, size_t i) { return v.begin() + std::ptrdiff_t(i); };
            std::merge(at(blocks, begin), at(blocks, mid), at(blocks, mid), at(blocks, end), at(merged, begin), less);
            next[k] = end;
        });
        blocks.swap(merged);
        ends = std::move(next);
    }
    blocks.erase(std::unique(blocks.begin(), blocks.end()), blocks.end());
    releaseDuplicatesRoom(blocks);
}

namespace {

void checkRange(const openvdb::CoordBBox& box, const char* what)
{
    // Blocks reach 8 voxels below a region and samples 1 voxel above it.
    for (int a = 0; a < 3; ++a)
        if (box.min()[a] - 8 < kEdgeKeyCoordMin || box.max()[a] + 1 > kEdgeKeyCoordMax) {
            std::ostringstream s;
            s << "the grid's " << what << " " << box << " lies outside the supported index range ["
              << kEdgeKeyCoordMin + 8 << ", " << kEdgeKeyCoordMax - 1 << "]";
            throw InputError(s.str());
        }
}

// Calls fn(axis, tileMin, tileExtents, side) for every face of a tile where the constant region
// across lies on the other side of the iso-value: the cells along it form a one-block shell.
// Part `part` of `parts` probes every parts-th tile (each part checks every tile's value). In a tree
// read in part, the tiles standing for absent lower nodes are none of the file's, and what lies across
// a face in such a node is what `absent` says.
template <typename TreeT, typename Fn>
void forEachTileShell(const TreeT& tree, const Classifier& c, Fn&& fn, size_t part = 0, size_t parts = 1,
                      const AbsentLowerProbe& absent = {})
{
    constexpr int kLowerTileDepth = int(TreeT::DEPTH) - 2;  // a tile of a lower internal node
    typename TreeT::ValueAllCIter it = tree.cbeginValueAll();
    it.setMaxDepth(TreeT::ValueAllCIter::LEAF_DEPTH - 1);
    bool leafThere = false;
    double valueThere = 0.0;
    for (size_t k = 0; it; ++it) {
        openvdb::CoordBBox box;
        it.getBoundingBox(box);
        if (absent && int(it.getDepth()) < kLowerTileDepth &&
            absent({box.min().x(), box.min().y(), box.min().z()}, leafThere, valueThere))
            continue;
        const double v = double(*it);
        const size_t index = k++;
        if (!std::isfinite(v)) {
            std::ostringstream s;
            s << "tile " << box << " holds a non-finite value (" << v << ")";
            throw InputError(s.str());
        }
        if (index % parts != part) continue;
        const bool in = c.inside(v);
        const int depth = int(it.getDepth());
        const openvdb::Coord lo = box.min(), size = box.extents();
        for (int axis = 0; axis < 3; ++axis) {
            for (int side = 0; side < 2; ++side) {
                openvdb::Coord across = lo;
                across[axis] = side ? lo[axis] + size[axis] : lo[axis] - 1;
                double acrossValue = 0.0;
                const bool unread = absent && absent({across.x(), across.y(), across.z()}, leafThere, acrossValue);
                const int acrossDepth = unread ? (leafThere ? kLowerTileDepth + 1 : kLowerTileDepth) : tree.getValueDepth(across);
                if (acrossDepth > depth) continue;            // finer structure: handled from there
                if (acrossDepth == depth && side == 0) continue;  // a tile of this size across: its +side reports it
                // (Read only here: a value in a leaf would load the leaf.)
                if (!unread) acrossValue = double(tree.getValue(across));
                if (c.inside(acrossValue) == in) continue;
                checkRange(box, "tile");
                fn(axis, lo, size, side);
            }
        }
    }
}

} // namespace

template <typename TreeT>
std::vector<BlockOrigin> collectBlocks(const TreeT& tree, const Classifier& c, size_t part, size_t parts,
                                       const AbsentLowerProbe& absent)
{
    // Leaves: the leaf's own block and the 7 blocks whose upper corners sample it. Most of those 7 are
    // leaves themselves; only the others are added, so the list is never 8x the leaf count: it is
    // built while the whole topology is in memory too. The leaves divide among threads (a large
    // volume has millions); the list is sorted at the end, so the order they add blocks in is free. The
    // tree is probed without an accessor: one caches a leaf's voxel buffer, which loads the leaf.
    using LeafT = typename TreeT::LeafNodeType;
    std::vector<const LeafT*> leaves;
    leaves.reserve(tree.leafCount());
    tree.getNodes(leaves);
    // This part's share of the leaves, in the tree's order.
    const size_t all = leaves.size();
    leaves.erase(leaves.begin() + std::ptrdiff_t(all * (part + 1) / parts), leaves.end());
    leaves.erase(leaves.begin(), leaves.begin() + std::ptrdiff_t(all * part / parts));
    std::vector<BlockOrigin> blocks(leaves.size());
    tbb::enumerable_thread_specific<std::vector<BlockOrigin>> below;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<BlockOrigin>& mine = below.local();
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const openvdb::Coord o = leaves[i]->origin();
            checkRange(leaves[i]->getNodeBoundingBox(), "leaf");
            blocks[i] = {o.x(), o.y(), o.z()};
            for (int d = 1; d < 8; ++d) {
                const BlockOrigin low = samplingBlock(blocks[i], d);
                if (!tree.probeConstLeaf(openvdb::Coord(low[0], low[1], low[2]))) mine.push_back(low);
            }
        }
    });
    for (const std::vector<BlockOrigin>& mine : below) blocks.insert(blocks.end(), mine.begin(), mine.end());
    // Tiles: faces where the constant region across is on the other side of the iso-value.
    forEachTileShell(tree, c, [&](int axis, const openvdb::Coord& lo, const openvdb::Coord& size, int side) {
        const int u = (axis + 1) % 3, w = (axis + 2) % 3;
        BlockOrigin b;
        b[axis] = side ? lo[axis] + size[axis] - 8 : lo[axis] - 8;
        for (int32_t i = lo[u] - 8; i <= lo[u] + size[u] - 8; i += 8)
            for (int32_t j = lo[w] - 8; j <= lo[w] + size[w] - 8; j += 8) {
                b[u] = i;
                b[w] = j;
                blocks.push_back(b);
            }
    }, part, parts, absent);
    sortBlocks(blocks);
    return blocks;
}

template <typename TreeT>
uint64_t countTileShellBlocks(const TreeT& tree, const Classifier& c, const AbsentLowerProbe& absent)
{
    uint64_t n = 0;
    forEachTileShell(tree, c, [&](int axis, const openvdb::Coord&, const openvdb::Coord& size, int) {
        n += uint64_t(size[(axis + 1) % 3] / 8 + 1) * uint64_t(size[(axis + 2) % 3] / 8 + 1);
    }, 0, 1, absent);
    return n;
}

template std::vector<BlockOrigin> collectBlocks<openvdb::FloatTree>(const openvdb::FloatTree&, const Classifier&, size_t, size_t,
                                                                    const AbsentLowerProbe&);
template std::vector<BlockOrigin> collectBlocks<openvdb::DoubleTree>(const openvdb::DoubleTree&, const Classifier&, size_t, size_t,
                                                                     const AbsentLowerProbe&);
template uint64_t countTileShellBlocks<openvdb::FloatTree>(const openvdb::FloatTree&, const Classifier&, const AbsentLowerProbe&);
template uint64_t countTileShellBlocks<openvdb::DoubleTree>(const openvdb::DoubleTree&, const Classifier&, const AbsentLowerProbe&);

} // namespace vdb_isosimp

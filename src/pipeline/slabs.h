// Slabs and the merge tree: how a run's blocks divide into independent pieces of work, how the
// pieces join, and which process (rank) does which part. Everything here depends on the block list
// alone, never on threads or ranks, so the output does not either.
#pragma once
#include "vdb/block_order.h"
#include "core/chunk_pool.h"
#include "core/edge_key.h"

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace vdb_isosimp {

// Blocks per slab when the options do not say: about 200k full-resolution faces on CT-like data, so
// a 448^3 volume gives about 90 slabs and a slab's batches stay a small part of it.
constexpr uint64_t kDefaultBlocksPerSlab = 2048;
// More slabs add seams, but the last slabs to finish hold up the joins above them: a few slabs per
// worker even out their unequal seconds (the 1024^3 gyroid's 2.1M blocks: 256 slabs left 64 threads'
// last slab ending 13 % after the mean, 1024 slabs 9 %; docs/scale.md).
constexpr size_t kMaxSlabs = 1024;

// The merge tree over slabs [0, S): node [l, r) with r - l > 1 joins its children [l, m) and [m, r)
// at m = mergeSplit(l, r), the left half the larger. Its depth is ceil(log2 S).
inline size_t mergeSplit(size_t l, size_t r) { return l + (r - l + 1) / 2; }

// The order blocks are extracted in, the merge tree's own: every node of the tree is a run of it, cut
// from its parent's run by the lexicographic order (lexBefore) along the longest axis of the parent's
// blocks, the lower part first; a slab is swept z, y, x. So a node's two children meet on about one
// plane across its shorter sides, and a slab is a brick: the seams that wait at full resolution for
// the join that closes them are as small as a cut of the volume allows, and they shrink from the root
// down (bands of rows swept z/y/x met on a full plane at every join above a band: docs/perf.md). The
// order stays monotone (each cut and the sweep are), which the modifiability rule needs
// (modifiability.h), and it orders any block origin, listed or not.
struct BlockOrder {
    struct Node {
        int32_t axis = -1;      // -1: a slab, swept z/y/x
        BlockOrigin boundary{}; // the right child's first block: the left child holds the blocks lexBefore it
        uint32_t left = 0, right = 0;
    };
    std::vector<Node> nodes;  // nodes[0] is the root; empty: plain z/y/x (one slab)
    size_t slabs() const { return nodes.empty() ? 1 : (nodes.size() + 1) / 2; }
    // Whether origin x lies before (-1), among (0) or after (1) slabs [l, r) in this order: it walks
    // down the nodes that straddle l or r only, so an order arranged for some slabs alone (a rank's,
    // arrangeBlocks) answers for those slabs and for every range of its nodes above them.
    int slabSide(const BlockOrigin& x, size_t l, size_t r) const
    {
        size_t nl = 0, nr = slabs(), id = 0;
        while (true) {
            if (nr <= l) return -1;
            if (nl >= r) return 1;
            if (l <= nl && nr <= r) return 0;
            const Node& s = nodes[id];  // a node across l or r: two or more slabs
            const size_t m = mergeSplit(nl, nr);
            if (lexBefore(x, s.boundary, s.axis)) {
                nr = m;
                id = s.left;
            } else {
                nl = m;
                id = s.right;
            }
        }
    }
    // The order itself, of an arrangement of every slab.
    bool operator()(const BlockOrigin& a, const BlockOrigin& b) const
    {
        for (uint32_t n = 0; n < nodes.size() && nodes[n].axis >= 0;) {
            const Node& s = nodes[n];
            const bool ra = !lexBefore(a, s.boundary, s.axis), rb = !lexBefore(b, s.boundary, s.axis);
            if (ra != rb) return rb;
            n = ra ? s.right : s.left;
        }
        return lexBefore(a, b, 2);
    }
};

// Puts the blocks (z/y/x-sorted, without duplicates) in the order of a merge tree over `slabs` slabs of
// equal block counts (splitSlabs), and returns that order. With `sweepPlace`: each block's place in the
// z/y/x order it came in (the blocks a block's samples reach lie a block, a row or a layer on there).
// Slabs [ownFirst, ownEnd) alone (a rank's): the nodes above them are cut and they are arranged, every
// other subtree keeps its blocks in its run unarranged, and its nodes unset: enough for slabSide on
// those slabs and the nodes above them, at a few passes over the blocks instead of one per level.
BlockOrder arrangeBlocks(std::vector<BlockOrigin>& blocks, size_t slabs, PooledVector<uint32_t>* sweepPlace = nullptr,
                         size_t ownFirst = 0, size_t ownEnd = SIZE_MAX);

// A run of consecutive blocks in block order, extracted and decimated by its own integrator.
struct Slab {
    size_t begin = 0, end = 0;
};

// How many slabs a list of `blocks` blocks is cut into: one per `blocksPerSlab` (rounded up), then
// up to a power of two, at most kMaxSlabs (a power of two too). The merge tree halves such a count
// exactly down to its slabs, so the slabs are bricks of one shape and 2^j ranks get equal shares of
// them (a rank with one slab more than the others holds them all up at the joins above it). Slabs
// hold 1/2 to 1 times `blocksPerSlab` blocks.
size_t slabCount(size_t blocks, uint64_t blocksPerSlab);

// Cuts the sorted blocks into `count` slabs of equal block counts (within one); a cut may fall
// anywhere, also inside a layer of blocks. Fewer slabs than `count` when there are fewer blocks.
std::vector<Slab> splitSlabs(const std::vector<BlockOrigin>& blocks, size_t count);

// The parent of node [nl, nr) in the subtree rooted at [l, r) (which must hold it and differ from it).
std::pair<size_t, size_t> parentNode(size_t l, size_t r, size_t nl, size_t nr);

// Which ranks work on node [l, r) of the tree, given ranks [a, b) for it: the children get shares
// of the ranks in proportion to their slabs (each at least one while there are two or more ranks).
// A node's result is made by the first rank of its share; a right child's first rank sends it there.
struct RankShare {
    size_t leftBegin, leftEnd, rightBegin, rightEnd;
};
RankShare splitRanks(size_t l, size_t r, size_t a, size_t b);

// The node of the tree rank `rank` of `ranks` makes and hands on (sends to its parent's rank, or
// writes the output if it is the root): [l, r) with that rank first in its share, and the share
// itself. `found` is false for a rank left without slabs (more ranks than slabs).
struct RankNode {
    bool found = false;
    size_t l = 0, r = 0, a = 0, b = 0;
    size_t parent = 0;  // the rank that receives it (for rank 0: none, it makes the root)
};
RankNode rankNode(size_t slabs, size_t rank, size_t ranks);

// The slabs rank `rank` extracts itself: [first, end), empty for a rank left without slabs. The rest of
// its node's slabs come from the ranks it receives from.
std::pair<size_t, size_t> rankSlabs(size_t slabs, size_t rank, size_t ranks);

// Where a vertex's edge lies in the block order: the vertex is made by the cells around its edge, and
// the first and last of those in block order (componentwise the lowest and the highest, so in any
// monotone order, as BlockOrder is) sit in the blocks `first` and `last` (block origins).
// A vertex is final inside a slab when both lie in it, and at a merge node when both lie in the
// node's slabs; otherwise it stays open, a seam vertex, until they do.
struct EdgeBlocks {
    BlockOrigin first, last;
};
EdgeBlocks edgeBlocks(EdgeKey key);

// Whether every cell around the edge lies in slabs [l, r) of `order`, i.e. the vertex is final once
// those slabs have joined. (Those cells are extracted, so their blocks are listed.)
bool edgeWithin(EdgeKey key, const BlockOrder& order, size_t l, size_t r);

} // namespace vdb_isosimp

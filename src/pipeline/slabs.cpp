#include "pipeline/slabs.h"

#include <algorithm>

namespace vdb_isosimp {

std::vector<Slab> splitSlabs(const std::vector<BlockOrigin>& blocks, size_t count)
{
    std::vector<Slab> slabs;
    size_t begin = 0;
    for (size_t s = 0; s < count && begin < blocks.size(); ++s) {
        size_t end = s + 1 == count ? blocks.size() : std::max(begin + 1, blocks.size() * (s + 1) / count);
        while (end < blocks.size() && blocks[end][2] == blocks[end - 1][2]) ++end;
        slabs.push_back({begin, end, blocks[begin][2]});
        begin = end;
    }
    if (begin < blocks.size()) slabs.back().end = blocks.size();
    return slabs;
}

} // namespace vdb_isosimp

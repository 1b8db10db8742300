// Vertex identity: a surface vertex lives on a cell edge, named by the edge's min voxel and its axis,
// packed into 64 bits (no floating-point hashing). 20 bits per coordinate, biased, so index
// coordinates must lie in [-2^19, 2^19); the volume reader checks that before any work.
#pragma once
#include <cstdint>

namespace vdb_isosimp {

using EdgeKey = uint64_t;

constexpr int32_t kEdgeKeyCoordMin = -(1 << 19);
constexpr int32_t kEdgeKeyCoordMax = (1 << 19) - 1;

inline EdgeKey makeEdgeKey(int32_t x, int32_t y, int32_t z, int axis)
{
    const uint64_t bias = 1u << 19, mask = (1u << 20) - 1;
    return ((uint64_t(x + bias) & mask) << 42) | ((uint64_t(y + bias) & mask) << 22) |
           ((uint64_t(z + bias) & mask) << 2) | uint64_t(axis);
}

struct EdgeCoord { int32_t x, y, z; int axis; };

inline EdgeCoord decodeEdgeKey(EdgeKey k)
{
    const int64_t bias = 1 << 19, mask = (1 << 20) - 1;
    return {int32_t(int64_t((k >> 42) & mask) - bias), int32_t(int64_t((k >> 22) & mask) - bias),
            int32_t(int64_t((k >> 2) & mask) - bias), int(k & 3)};
}

} // namespace vdb_isosimp

// Slabs: runs of whole block layers (equal z), each extracted and decimated on its own by its own
// integrator and joined in order by the pipeline.
#pragma once
#include "vdb/block_order.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace vdb_isosimp {

// How many slabs a volume is cut into: a constant, so that the output never depends on the number of
// threads; the memory estimate counts their open seams.
constexpr size_t kPipelineSlabs = 8;

// A run of whole block layers (equal z), processed by its own integrator.
struct Slab {
    size_t begin = 0, end = 0;
    int32_t zStart = 0;
};

// Splits the z/y/x-sorted blocks into at most `count` slabs of about equal block counts, cutting only
// between block layers. The split depends on the volume alone, never on the thread count, so the
// output does not either.
std::vector<Slab> splitSlabs(const std::vector<BlockOrigin>& blocks, size_t count);

} // namespace vdb_isosimp

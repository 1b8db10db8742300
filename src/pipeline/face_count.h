// A face target's count (Options::targetFaces): the faces of the full-resolution surface over every
// block, or on a large volume over a stratified sample of runs of blocks, and the estimate and margin
// the sample gives. Like the slabs, what is sampled depends on the block list alone.
#pragma once
#include "core/marching_cubes.h"
#include "pipeline/slabs.h"
#include "vdb/block_order.h"
#include "vdb/volume_reader.h"

#include <cstddef>
#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

namespace vdb_isosimp {

// A sampled count whose margin would pass this (a surface in few of the blocks, say a small blob in a
// large fog) is not used: every block is counted then.
constexpr double kCountMarginMost = 0.1;

// The runs of 64 consecutive blocks, each within one slab (so a rank's runs are whole, whatever the
// ranks), that a face target's count reads: all of them while there are fewer than twice
// `sampleRuns` (0: always all), else one of each `stride` consecutive ones, at least `sampleRuns`: a
// stratified sample over the blocks in tree order, i.e. spread over the whole volume. Within its
// stride, the place of a sampled run is a hash of the stride's number, so the samples do not fall at
// the same place of every subtree of the tree order (such as each slab's first run, on the volume's
// shell).
struct CountRuns {
    std::vector<std::pair<size_t, size_t>> all;  // [begin, end) of every run, in block order
    std::vector<size_t> sampled;                  // indices into `all`, increasing
    size_t stride = 1;
};
CountRuns countRuns(const std::vector<Slab>& slabs, uint64_t sampleRuns);

// Faces of the sampled runs and the sum of their squares (the sample's spread says how far the
// estimate may be off).
struct FaceCount {
    uint64_t faces = 0, squares = 0;
};

// The faces of the sampled runs within blocks [begin, end) (all of them, exact, at stride 1): the same
// case table over the same blocks as extraction. `counted` hears the fraction of runs counted, in
// order; false from it cancels.
FaceCount countFaces(const Volume& vol, const std::vector<BlockOrigin>& blocks, const CountRuns& plan, size_t begin,
                     size_t end, const Classifier& cls, const std::function<bool(double)>& counted);

// The full faces a sample of `blocks` blocks that counted `count` estimates, and how far below that
// a rate should take them: three standard errors of the estimate, at least 1 %; 1 where the sample
// says nothing.
double estimatedFaces(const CountRuns& plan, size_t blocks, const FaceCount& count);
double estimateMargin(const CountRuns& plan, const FaceCount& count);

} // namespace vdb_isosimp

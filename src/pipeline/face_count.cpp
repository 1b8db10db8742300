#include "pipeline/face_count.h"
#include "pipeline/pipeline_internal.h"

#include "vdb_isosimp/errors.h"

#include <tbb/parallel_pipeline.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <thread>

namespace vdb_isosimp {

namespace {

constexpr size_t kCountRun = 64;
// The rate a sampled count gives is raised by this many standard errors of its estimate (at least 1 %):
// the slabs keep at least the target between them, and the final pass takes the rest off.
constexpr double kCountMarginErrors = 3.0, kCountMarginLeast = 0.01;

} // namespace

CountRuns countRuns(const std::vector<Slab>& slabs, uint64_t sampleRuns)
{
    CountRuns c;
    for (const Slab& slab : slabs)
        for (size_t b = slab.begin; b < slab.end; b += kCountRun) c.all.push_back({b, std::min(slab.end, b + kCountRun)});
    c.stride = sampleRuns == 0 ? 1 : std::max<size_t>(1, c.all.size() / sampleRuns);
    for (size_t first = 0; first < c.all.size(); first += c.stride) {
        uint64_t h = (uint64_t(first) + 1) * 0x9E3779B97F4A7C15ull;  // a fixed mix of the stratum's number
        h ^= h >> 29;
        h *= 0xBF58476D1CE4E5B9ull;
        h ^= h >> 32;
        c.sampled.push_back(first + (c.stride == 1 ? 0 : size_t(h % std::min(c.stride, c.all.size() - first))));
    }
    return c;
}

// It reads copies of the leaves (Volume::CopyReader), so the volume stays as opened for extraction, and
// frees each copy once its last block is counted (blocks in order, as in extraction), so counting does
// not load the whole volume at once. The blocks go to the threads in runs of consecutive ones: a block
// alone is too little work to hand on, and two threads on consecutive blocks keep meeting on the load
// lock of the leaf they share.
FaceCount countFaces(const Volume& vol, const std::vector<BlockOrigin>& blocks, const CountRuns& plan, size_t begin,
                     size_t end, const Classifier& cls, const std::function<bool(double)>& counted)
{
    constexpr size_t kRun = kCountRun;
    // The input mapping is trimmed as each run is added (below), once per kCountRun blocks a thread: no
    // more often than extraction does it (each trim flushes the other threads' TLBs).
    static_assert(kRun <= Volume::kTrimEveryBlocks, "a run's pages stay mapped until it is added");
    std::vector<std::pair<size_t, size_t>> mine;
    for (size_t r : plan.sampled)
        if (plan.all[r].first >= begin && plan.all[r].second <= end) mine.push_back(plan.all[r]);
    const size_t runs = mine.size();
    if (runs == 0) return {};
    const auto runBlocks = [&](size_t run) { return mine[run]; };
    // Every run: copies shared by all, each freed by its own block. Sampled runs: each its own copies
    // (a run's blocks read leaves of the blocks after it, which are not counted and would not free them).
    const std::unique_ptr<Volume::CopyReader> copies = plan.stride == 1 ? vol.copyReader() : nullptr;
    const auto count = [&](size_t run) {
        const auto [first, last] = runBlocks(run);
        uint64_t faces = 0;
        BlockSamples s;
        const std::unique_ptr<Volume::CopyReader> own = copies ? nullptr : vol.privateCopyReader();
        Volume::CopyReader& reader = copies ? *copies : *own;
        for (size_t i = first; i < last; ++i) {
            reader.sample(blocks[i], s);
            faces += countBlockTriangles(s, cls);
        }
        return std::make_pair(run, faces);
    };
    FaceCount total;
    const auto add = [&](std::pair<size_t, uint64_t> run) {
        total.faces += run.second;
        total.squares += run.second * run.second;
        const auto [first, last] = runBlocks(run.first);
        if (copies)
            for (size_t i = first; i < last; ++i) copies->release(blocks[i]);
        if (!vol.readsStoredRecords()) vol.trimInputMapping();
        static_assert(kProgressEveryBlocks % kRun == 0, "the count reports after whole runs");
        constexpr size_t kReportEveryRuns = kProgressEveryBlocks / kRun;
        if (((run.first + 1) % kReportEveryRuns == 0 || run.first + 1 == runs) && !counted(double(run.first + 1) / double(runs)))
            throw Cancelled("cancelled");
    };
    size_t next = 0;
    tbb::parallel_pipeline(4 * std::max<size_t>(1, std::thread::hardware_concurrency()),
                           indices(next, runs) &
                               tbb::make_filter<size_t, std::pair<size_t, uint64_t>>(tbb::filter_mode::parallel, count) &
                               tbb::make_filter<std::pair<size_t, uint64_t>, void>(tbb::filter_mode::serial_in_order, add));
    return total;
}

double estimatedFaces(const CountRuns& plan, size_t blocks, const FaceCount& count)
{
    size_t sampled = 0;
    for (size_t r : plan.sampled) sampled += plan.all[r].second - plan.all[r].first;
    return sampled > 0 ? double(count.faces) * double(blocks) / double(sampled) : 0.0;
}

// The standard error from the spread of the sampled runs' faces, as for a simple random sample of
// runs (which a stratified one does not exceed).
double estimateMargin(const CountRuns& plan, const FaceCount& count)
{
    const double n = double(plan.sampled.size()), runs = double(plan.all.size());
    const double faces = double(count.faces), squares = double(count.squares);
    if (n < 2 || faces <= 0) return 1.0;
    const double mean = faces / n, variance = std::max(0.0, (squares - faces * mean) / (n - 1));
    return std::max(kCountMarginLeast, kCountMarginErrors * std::sqrt(variance / n * (1.0 - n / runs)) / mean);
}

} // namespace vdb_isosimp

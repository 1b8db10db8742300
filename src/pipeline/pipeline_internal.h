// Internal seam between the pipeline driver (pipeline.cpp) and its entry points (pipeline_grid.cpp).
#pragma once
#include "vdb/volume_reader.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <tbb/parallel_pipeline.h>

#include <array>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace vdb_isosimp {

// First stage of the pipelines over blocks (extraction, the face count): next, next + 1, ... up to end (exclusive), in order. The counter
// lives with the caller: TBB calls stage bodies as const.
inline tbb::filter<void, size_t> indices(size_t& next, size_t end)
{
    return tbb::make_filter<void, size_t>(tbb::filter_mode::serial_in_order, [&next, end](tbb::flow_control& fc) -> size_t {
        if (next == end) {
            fc.stop();
            return 0;
        }
        return next++;
    });
}

// Progress is reported once per this many blocks, extracted or counted.
constexpr size_t kProgressEveryBlocks = 256;

// The whole pipeline on the volume `open` returns (called once, after the options are checked):
// `name` is what Report::file holds and what every InputError / EmptySurfaceError message starts
// with. simplifyFile(path) is simplifyVolume([&] { return Volume::open(path, o.gridName); }, path, ...);
// simplifyGrid() passes Volume::fromGrid(), which reads the caller's grid in place.
using VolumeOpener = std::function<std::unique_ptr<Volume>()>;

// The processes of a distributed run (mpi/): each opens the volume itself, runs its part of the
// merge tree (slabs.h: rankNode) and sends the result to the rank of the parent node.
class RankChannel {
public:
    virtual ~RankChannel() = default;
    virtual size_t rank() const = 0;
    virtual size_t ranks() const = 0;
    // CPU seconds this process has spent in the collectives below and in the agreement on the stored
    // tree (waiting for the other ranks included), so far.
    virtual double collectiveCpuSeconds() const { return 0.0; }
    // Called by every rank once its block list is known (`error` empty) or its start failed (the
    // message): when all agree on `blocks`, returns the sums of every rank's `counts` (what each
    // counted for a face target); otherwise throws on every rank, on rank 0 the first failed rank's
    // message.
    virtual std::array<uint64_t, 2> agree(const std::string& error, uint64_t blocks, std::array<uint64_t, 2> counts) = 0;
    // Called by every rank once as the iso-value is chosen, with the value range of its part of the
    // leaves where a fog grid's default iso-value needs it (else an empty one), or `failed` when
    // reading them threw or the rank failed before (its open): returns the smallest and largest of
    // all ranks. Throws PeerFailed on a rank that did not fail when another did (agree() then
    // carries that rank's message to rank 0).
    virtual std::array<double, 2> agreeRange(std::array<double, 2> range, bool failed) = 0;
    // Called by every rank once its part of the block list is collected (`blocks`, sorted; `failed`:
    // collecting it threw): every rank's part in rank order replaces `blocks`, and `runEnds` gets where
    // each ends. Throws PeerFailed on a rank that did not fail when another did (agree() then carries
    // that rank's message to rank 0).
    virtual void gatherBlocks(std::vector<std::array<int32_t, 3>>& blocks, std::vector<size_t>& runEnds, bool failed) = 0;
    // Hands a finished node to rank `to` (or, `error` not empty, the error that stopped it).
    virtual void send(size_t to, const std::vector<char>& bytes, const std::string& error) = 0;
    // The node rank `from` sends; throws the error it sent instead.
    virtual std::vector<char> receive(size_t from) = 0;
};

// `ranks`: this process's share of a distributed run, or null for all of it. With ranks, only rank 0's
// Result holds the mesh; the others return their own report (their seconds and peak memory).
Result simplifyVolume(const VolumeOpener& open, const std::string& name, const Options& options, Progress* progress,
                      RankChannel* ranks = nullptr);

} // namespace vdb_isosimp

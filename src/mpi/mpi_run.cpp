// The merge tree's messages between MPI ranks (pipeline_internal.h: RankChannel). A message is a header
// (ok or failed, payload bytes) and the payload: a node's bytes or the error that stopped it. Every
// message a rank waits for is sent, failed or not, so an error anywhere ends every rank.
#include "vdb_isosimp/mpi_run.h"

#include "core/huge_pages.h"
#include "pipeline/pipeline_internal.h"
#include "pipeline/run_stats.h"
#include "vdb_isosimp/errors.h"

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <vector>

#ifdef VDB_ISOSIMP_HAVE_MPI
#include <mpi.h>
#endif

namespace vdb_isosimp {

bool startedByMpirun()
{
    return std::getenv("OMPI_COMM_WORLD_SIZE") != nullptr || std::getenv("PMIX_RANK") != nullptr;
}

#ifdef VDB_ISOSIMP_HAVE_MPI

namespace {

constexpr int kNodeTag = 16, kAgreeTag = 17;
// MPI counts are ints: payloads go in parts of at most 1 GiB.
constexpr uint64_t kPart = uint64_t(1) << 30;

void check(int code, const char* what)
{
    if (code != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + what + " failed");
}

void sendPayload(const char* data, uint64_t size, int to, int tag)
{
    const uint64_t header = size;
    check(MPI_Send(&header, 1, MPI_UINT64_T, to, tag, MPI_COMM_WORLD), "send");
    for (uint64_t done = 0; done < size; done += kPart)
        check(MPI_Send(data + done, int(std::min(kPart, size - done)), MPI_BYTE, to, tag, MPI_COMM_WORLD), "send");
}

std::vector<char> receivePayload(int from, int tag)
{
    uint64_t size = 0;
    check(MPI_Recv(&size, 1, MPI_UINT64_T, from, tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE), "receive");
    std::vector<char> data(size);
    for (uint64_t done = 0; done < size; done += kPart)
        check(MPI_Recv(data.data() + done, int(std::min(kPart, size - done)), MPI_BYTE, from, tag, MPI_COMM_WORLD,
                       MPI_STATUS_IGNORE),
              "receive");
    return data;
}

class MpiChannel final : public RankChannel {
public:
    MpiChannel(int rank, int ranks) : mRank(rank), mRanks(ranks) {}
    size_t rank() const override { return size_t(mRank); }
    size_t ranks() const override { return size_t(mRanks); }
    double collectiveCpuSeconds() const override { return mCollectiveCpu; }

    // Counts the CPU seconds of a collective while it lives.
    class Collective {
    public:
        explicit Collective(MpiChannel& c) : mChannel(c), mStart(processCpuSeconds()) {}
        ~Collective() { mChannel.mCollectiveCpu += processCpuSeconds() - mStart; }
        Collective(const Collective&) = delete;
        Collective& operator=(const Collective&) = delete;

    private:
        MpiChannel& mChannel;
        double mStart;
    };

    std::array<uint64_t, 2> agree(const std::string& error, uint64_t blocks, std::array<uint64_t, 2> counts) override
    {
        const Collective timed(*this);
        constexpr size_t kWords = 4;
        const uint64_t mine[kWords] = {error.empty() ? 0u : 1u, blocks, counts[0], counts[1]};
        std::vector<uint64_t> all(kWords * size_t(mRanks));
        check(MPI_Allgather(mine, kWords, MPI_UINT64_T, all.data(), kWords, MPI_UINT64_T, MPI_COMM_WORLD), "allgather");
        int failed = -1;
        for (int r = 0; r < mRanks && failed < 0; ++r)
            if (all[kWords * size_t(r)]) failed = r;
        if (failed < 0) {
            std::array<uint64_t, 2> sums{0, 0};
            for (int r = 0; r < mRanks; ++r) {
                const uint64_t* theirs = &all[kWords * size_t(r)];
                sums[0] += theirs[2];
                sums[1] += theirs[3];
                if (theirs[1] == all[1]) continue;
                if (mRank == 0)
                    throw InputError("ranks 0 and " + std::to_string(r) + " read different block lists (" +
                                     std::to_string(all[1]) + " and " + std::to_string(theirs[1]) +
                                     " blocks): the file changed or differs between machines");
                throw PeerFailed("ranks disagree on the input");
            }
            return sums;
        }
        // The first failed rank's message goes to rank 0, which reports it.
        if (failed > 0 && mRank == failed) sendPayload(error.data(), error.size(), 0, kAgreeTag);
        std::string message = error;
        if (failed > 0 && mRank == 0) {
            const std::vector<char> text = receivePayload(failed, kAgreeTag);
            message.assign(text.begin(), text.end());
        }
        if (!error.empty()) return {0, 0};  // the caller goes on with its own error
        if (mRank == 0) throw InputError(message + " (rank " + std::to_string(failed) + ")");
        throw PeerFailed("rank " + std::to_string(failed) + " failed");
    }

    std::array<double, 2> agreeRange(std::array<double, 2> range, bool failed) override
    {
        const Collective timed(*this);
        // The largest of: a failure, minus the smallest value, the largest value.
        const double mine[3] = {failed ? 1.0 : 0.0, -range[0], range[1]};
        double most[3] = {0.0, 0.0, 0.0};
        check(MPI_Allreduce(mine, most, 3, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD), "allreduce");
        if (most[0] > 0.0 && !failed) throw PeerFailed("another rank failed reading the value range");
        return {-most[1], most[2]};
    }

    void gatherBlocks(std::vector<std::array<int32_t, 3>>& blocks, std::vector<size_t>& runEnds, bool failed) override
    {
        const Collective timed(*this);
        // Each rank's failure and block count, then the blocks themselves (counts in blocks: MPI's
        // ints count up to 2^31 of them a rank).
        const uint64_t mine[2] = {failed ? 1u : 0u, failed ? 0u : blocks.size()};
        std::vector<uint64_t> all(2 * size_t(mRanks));
        check(MPI_Allgather(mine, 2, MPI_UINT64_T, all.data(), 2, MPI_UINT64_T, MPI_COMM_WORLD), "allgather");
        std::vector<int> counts(static_cast<size_t>(mRanks)), displs(static_cast<size_t>(mRanks));
        uint64_t total = 0;
        bool anyFailed = false;
        runEnds.clear();
        for (int r = 0; r < mRanks; ++r) {
            anyFailed = anyFailed || all[2 * size_t(r)] != 0;
            if (all[2 * size_t(r) + 1] > uint64_t(std::numeric_limits<int>::max()) ||
                total > uint64_t(std::numeric_limits<int>::max()))
                throw InputError("the block list is too long to share among ranks (" + std::to_string(all[2 * size_t(r) + 1]) +
                                 " blocks on rank " + std::to_string(r) + ")");
            displs[size_t(r)] = int(total);
            counts[size_t(r)] = int(all[2 * size_t(r) + 1]);
            total += all[2 * size_t(r) + 1];
            runEnds.push_back(size_t(total));
        }
        if (anyFailed) {
            if (failed) return;  // the caller goes on with its own error
            throw PeerFailed("another rank failed listing its blocks");
        }
        MPI_Datatype block;
        check(MPI_Type_contiguous(3, MPI_INT32_T, &block), "type");
        check(MPI_Type_commit(&block), "type");
        // The whole list, 25 MB on the 2 GB gyroid, fresh on every rank: in huge pages, a page fault for
        // every 2 MiB instead of every 4 KiB.
        std::vector<std::array<int32_t, 3>> gathered;
        gathered.reserve(total);
        adviseHugePages(gathered.data(), total * sizeof(gathered[0]));
        gathered.resize(total);
        const int code = MPI_Allgatherv(blocks.data(), int(blocks.size()), block, gathered.data(), counts.data(),
                                        displs.data(), block, MPI_COMM_WORLD);
        MPI_Type_free(&block);
        check(code, "allgatherv");
        blocks = std::move(gathered);
    }

    void send(size_t to, const std::vector<char>& bytes, const std::string& error) override
    {
        const uint64_t failed = error.empty() ? 0 : 1;
        check(MPI_Send(&failed, 1, MPI_UINT64_T, int(to), kNodeTag, MPI_COMM_WORLD), "send");
        if (failed) sendPayload(error.data(), error.size(), int(to), kNodeTag);
        else sendPayload(bytes.data(), bytes.size(), int(to), kNodeTag);
    }

    std::vector<char> receive(size_t from) override
    {
        uint64_t failed = 0;
        check(MPI_Recv(&failed, 1, MPI_UINT64_T, int(from), kNodeTag, MPI_COMM_WORLD, MPI_STATUS_IGNORE), "receive");
        std::vector<char> payload = receivePayload(int(from), kNodeTag);
        if (failed) {
            const std::string message(payload.begin(), payload.end());
            if (mRank == 0) throw InputError(message);
            throw PeerFailed(message);
        }
        return payload;
    }

private:
    int mRank, mRanks;
    double mCollectiveCpu = 0.0;
};

} // namespace

MpiRun::MpiRun(int& argc, char**& argv)
{
    int provided = 0;
    if (MPI_Init_thread(&argc, &argv, MPI_THREAD_SERIALIZED, &provided) != MPI_SUCCESS)
        throw std::runtime_error("MPI could not start");
    // Messages are sent from whichever thread runs the tree, one at a time.
    if (provided < MPI_THREAD_SERIALIZED) {
        MPI_Finalize();
        throw std::runtime_error("this MPI library cannot be called from more than one thread");
    }
    MPI_Comm_rank(MPI_COMM_WORLD, &mRank);
    MPI_Comm_size(MPI_COMM_WORLD, &mRanks);
}

MpiRun::~MpiRun()
{
    MPI_Finalize();
}

Result MpiRun::simplifyFile(const std::string& path, const Options& options, Progress* progress)
{
    MpiChannel channel(mRank, mRanks);
    // Each rank walks its part of the leaf records (and later those of the leaves it reads); their
    // stored trees must be one.
    TreeAgreement agreement;
    agreement.part = size_t(mRank);
    agreement.parts = size_t(mRanks);
    agreement.agree = [&channel](bool walked, bool sound, uint64_t digest) {
        const MpiChannel::Collective timed(channel);
        // The largest of: "did not walk", "not sound", the digest, its complement (so the smallest digest too).
        const uint64_t mine[4] = {walked ? 0u : 1u, sound ? 0u : 1u, digest, ~digest};
        uint64_t most[4] = {0, 0, 0, 0};
        check(MPI_Allreduce(mine, most, 4, MPI_UINT64_T, MPI_MAX, MPI_COMM_WORLD), "allreduce");
        // A mesh made of both would be neither file's. Every rank throws the same error.
        if (most[0] == 0 && most[2] != ~most[3])
            throw InputError("the ranks read different files under this path (their stored trees differ): the file "
                             "changed, or differs between machines");
        return most[0] == 0 && most[1] == 0;
    };
    return simplifyVolume([&] { return Volume::open(path, options.gridName, agreement); }, path, options, progress, &channel);
}

#else

MpiRun::MpiRun(int&, char**&)
{
    throw std::runtime_error("started by mpirun, but this build has no MPI (install libopenmpi-dev and rebuild)");
}

MpiRun::~MpiRun() = default;

Result MpiRun::simplifyFile(const std::string& path, const Options& options, Progress* progress)
{
    return vdb_isosimp::simplifyFile(path, options, progress);
}

#endif

} // namespace vdb_isosimp

// Distributed runs: `mpirun -np N vdb_isosimp in.vdb ...`. Every rank opens the file itself (delayed
// loading: it reads the topology and the leaves of its own slabs only), makes its node of the merge
// tree from its slabs with its threads, and sends the result to the rank that makes the parent node;
// rank 0 makes the root and runs the final pass. The output is the same bytes for any number of ranks
// and threads.
#pragma once
#include "vdb_isosimp/vdb_isosimp.h"

#include <string>

namespace vdb_isosimp {

// True when mpirun started this process (Open MPI's environment is set), before MPI is initialised.
bool startedByMpirun();

// MPI for the lifetime of the object.
class MpiRun {
public:
    // Initialises MPI. @throw std::runtime_error when this build has no MPI or MPI cannot start.
    MpiRun(int& argc, char**& argv);
    ~MpiRun();
    MpiRun(const MpiRun&) = delete;
    MpiRun& operator=(const MpiRun&) = delete;

    int rank() const { return mRank; }
    int ranks() const { return mRanks; }

    // simplifyFile across the ranks. Rank 0 gets the mesh and a report with every rank's seconds and
    // peak memory (Report::rankSeconds, rankPeakRssMb); the other ranks get their own report and no
    // mesh. @throw as simplifyFile, on every rank when any rank fails: on rank 0 with the failed rank's
    // message, on the others PeerFailed (errors.h) unless the error is their own.
    Result simplifyFile(const std::string& vdbPath, const Options& options, Progress* progress = nullptr);

private:
    int mRank = 0, mRanks = 1;
};

} // namespace vdb_isosimp

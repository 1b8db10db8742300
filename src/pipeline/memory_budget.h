// The run's peak memory, estimated from the opened grid's topology before any voxel is read, against
// a budget (Options::maxMemoryBytes; the program's default is the machine's memory).
#pragma once
#include "vdb/volume_reader.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <cstdint>
#include <string>

namespace vdb_isosimp {

// Peak memory of a run, estimated from the topology alone (no voxel read). Parts in bytes.
struct MemoryEstimate {
    uint64_t topology = 0;  // tree nodes (voxel buffers not counted)
    uint64_t voxels = 0;    // voxel buffers alive at once
    uint64_t blocks = 0;    // the block list
    uint64_t mesh = 0;      // intermediate and final mesh
    uint64_t base = 0;      // program, libraries, thread stacks
    uint64_t total() const { return topology + voxels + blocks + mesh + base; }
};

// `tileShellBlocks`: the blocks along tile faces that cross the iso-value (countTileShellBlocks), each
// a flat 8x8 patch of cells, which the leaf count does not show.
MemoryEstimate estimateMemory(const VolumeInfo& info, const Options& options, uint64_t tileShellBlocks = 0);

// "1.5 GiB", "300 MiB".
std::string formatBytes(uint64_t bytes);

// Estimates the run's memory from the opened grid's topology and throws InputError naming the file
// when it exceeds `limitBytes` (0: no limit). Returns the estimate.
MemoryEstimate checkMemoryBudget(const std::string& path, const VolumeInfo& info, const Options& options,
                                 uint64_t limitBytes, uint64_t tileShellBlocks = 0);

} // namespace vdb_isosimp

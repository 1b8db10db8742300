#include "pipeline/memory_budget.h"

#include "vdb_isosimp/errors.h"

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <unistd.h>

namespace vdb_isosimp {

namespace {
// The decimator holds about 300 bytes per face of the intermediate mesh (vertices, quadrics,
// adjacency, queue), and a leaf crossed by the surface yields up to ~170 faces of the full-resolution
// surface (a gyroid filling the box; a narrow-band level set yields fewer per leaf): docs/perf.md.
constexpr double kBytesPerFace = 300.0;
constexpr double kFacesPerLeaf = 170.0;
constexpr double kFacesPerShellBlock = 128.0;  // two triangles per cell of a flat 8x8 patch
constexpr uint64_t kBaseBytes = 64ull << 20;
constexpr uint64_t kLiveLeafLayers = 17;
} // namespace

MemoryEstimate estimateMemory(const VolumeInfo& info, const Options& o, uint64_t tileShellBlocks)
{
    MemoryEstimate e;
    e.base = kBaseBytes;
    e.topology = info.topologyBytes;
    // Live voxels: per slab in progress the layer being extracted and the one above it (a slab per
    // thread, up to 8 counted), plus the leaves shared with the next slab, kept until it has read them.
    e.voxels = kLiveLeafLayers * info.maxLeavesPerLayer * 512u * info.valueBytes;
    // 8 candidate blocks per leaf of 12 bytes, doubled for the vector's growth and the sort.
    e.blocks = (info.leafCount * 8u + tileShellBlocks) * 12u * 2u;
    const double fullFaces = kFacesPerLeaf * double(info.leafCount) + kFacesPerShellBlock * double(tileShellBlocks);
    const double kept = o.targetFaces > 0 ? std::min(double(o.targetFaces), fullFaces) : o.ratio * fullFaces;
    const double faces = kept + 2.0 * double(o.batchFaces);
    const double bytes = kBytesPerFace * faces;
    e.mesh = bytes >= 1.8e19 ? uint64_t(1.8e19) : uint64_t(bytes);
    return e;
}

uint64_t machineMemoryBytes()
{
    const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
    uint64_t mem = pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : 0;
    // A container's limit (cgroup v2, then v1) is what the kernel enforces.
    for (const char* f : {"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"}) {
        std::ifstream in(f);
        std::string s;
        if (!(in >> s) || s == "max") continue;
        char* end = nullptr;
        errno = 0;
        const unsigned long long v = std::strtoull(s.c_str(), &end, 10);
        if (errno == 0 && end && *end == '\0' && v > 0 && (mem == 0 || v < mem)) mem = v;
    }
    return mem;
}

std::string formatBytes(uint64_t b)
{
    char buf[48];
    const double x = double(b);
    if (x >= 1024.0 * 1024 * 1024) std::snprintf(buf, sizeof buf, "%.1f GiB", x / (1024.0 * 1024 * 1024));
    else std::snprintf(buf, sizeof buf, "%.0f MiB", x / (1024.0 * 1024));
    return buf;
}

MemoryEstimate checkMemoryBudget(const std::string& path, const VolumeInfo& info, const Options& options,
                                 uint64_t limit, uint64_t tileShellBlocks)
{
    const MemoryEstimate e = estimateMemory(info, options, tileShellBlocks);
    if (limit > 0 && e.total() > limit) {
        std::ostringstream s;
        s << path << ": estimated peak memory " << formatBytes(e.total()) << " exceeds the limit of "
          << formatBytes(limit) << " (grid '" << info.gridName << "': " << info.leafCount << " leaves";
        if (tileShellBlocks > 0) s << " and " << tileShellBlocks << " blocks along tile faces";
        s << "; mesh " << formatBytes(e.mesh) << ", topology " << formatBytes(e.topology)
          << "); lower the ratio, the face target or the batch size, or raise the memory limit";
        throw MemoryBudgetError(s.str());
    }
    return e;
}

} // namespace vdb_isosimp

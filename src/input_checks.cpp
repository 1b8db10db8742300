#include "input_checks.h"
#include "pipeline_internal.h"

#include "edge_key.h"
#include "errors.h"

#include <openvdb/math/Transform.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <sys/stat.h>
#include <unistd.h>

namespace vdb_isosimp {

// ---------------------------------------------------------------------------------------------
// File structure

namespace {

// Bounded little-endian reads from a file: every length read from the file is checked against the
// bytes that are left before anything is skipped or allocated.
class BoundedReader {
public:
    BoundedReader(const std::string& path, uint64_t size) : mIn(path, std::ios::binary), mSize(size) {}
    bool ok() const { return bool(mIn); }
    uint64_t pos() const { return mPos; }
    uint64_t left() const { return mSize - mPos; }

    bool bytes(void* dst, uint64_t n)
    {
        if (n > left()) return false;
        mIn.read(static_cast<char*>(dst), std::streamsize(n));
        if (!mIn) return false;
        mPos += n;
        return true;
    }
    bool skip(uint64_t n)
    {
        if (n > left()) return false;
        return seek(mPos + n);
    }
    bool seek(uint64_t p)
    {
        if (p > mSize) return false;
        mIn.seekg(std::streamoff(p));
        if (!mIn) return false;
        mPos = p;
        return true;
    }
    template <typename T> bool value(T& v) { return bytes(&v, sizeof v); }
    // OpenVDB string: uint32 length, then the characters. Keeps at most `keep` of them.
    bool string(std::string* out, size_t keep = 256)
    {
        uint32_t n = 0;
        if (!value(n) || n > left()) return false;
        if (!out) return skip(n);
        const uint32_t k = uint32_t(std::min<size_t>(n, keep));
        out->resize(k);
        return bytes(&(*out)[0], k) && skip(n - k);
    }

private:
    std::ifstream mIn;
    uint64_t mSize;
    uint64_t mPos = 0;
};

[[noreturn]] void damaged(const std::string& path, const std::string& what)
{
    throw InputError(path + ": truncated or damaged OpenVDB file (" + what + ")");
}

} // namespace

void checkVdbFileStructure(const std::string& path)
{
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0)
        throw InputError(path + ": cannot open file for reading (" + std::strerror(errno) + ")");
    if (S_ISDIR(st.st_mode)) throw InputError(path + ": is a directory, not a .vdb file");
    if (!S_ISREG(st.st_mode)) return;  // pipes and devices cannot be checked without consuming them
    const uint64_t size = uint64_t(st.st_size);
    BoundedReader in(path, size);
    if (!in.ok()) throw InputError(path + ": cannot open file for reading (" + std::strerror(errno) + ")");

    int64_t magic = 0;
    if (!in.value(magic) || int32_t(magic) != openvdb::OPENVDB_MAGIC)
        throw InputError(path + ": not a readable OpenVDB file (no VDB magic number)");
    uint32_t version = 0, major = 0, minor = 0;
    char hasOffsets = 0;
    if (!in.value(version)) damaged(path, "header ends early");
    // Older layouts (before 2013) differ in their header; OpenVDB alone reads them.
    if (version < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) return;
    if (!in.value(major) || !in.value(minor) || !in.value(hasOffsets) || !in.skip(36))  // 36: UUID text
        damaged(path, "header ends early");
    if (!hasOffsets) return;  // written as a stream: no offsets to check

    // File-level metadata: count, then (name, type, byte count, bytes) per item.
    uint32_t count = 0;
    if (!in.value(count) || count > in.left() / 12) damaged(path, "file metadata ends early");
    for (uint32_t i = 0; i < count; ++i) {
        uint32_t n = 0;
        if (!in.string(nullptr) || !in.string(nullptr) || !in.value(n) || !in.skip(n))
            damaged(path, "file metadata ends early");
    }

    int32_t grids = 0;
    if (!in.value(grids) || grids < 0 || uint64_t(grids) > in.left() / 36) damaged(path, "grid count ends early or is invalid");
    for (int32_t g = 0; g < grids; ++g) {
        std::string name;
        int64_t gridPos = 0, blockPos = 0, endPos = 0;
        if (!in.string(&name) || !in.string(nullptr) || !in.string(nullptr) || !in.value(gridPos) ||
            !in.value(blockPos) || !in.value(endPos))
            damaged(path, "descriptor of grid " + std::to_string(g + 1) + " of " + std::to_string(grids) + " ends early");
        name = name.substr(0, name.find('\x1e'));  // unique-name suffix of repeated names
        for (char& c : name)
            if (static_cast<unsigned char>(c) < 0x20) c = '?';
        const uint64_t here = in.pos();
        const bool ordered = gridPos >= 0 && uint64_t(gridPos) >= here && endPos >= gridPos &&
                             (blockPos == 0 || (blockPos >= gridPos && blockPos <= endPos));
        if (!ordered) damaged(path, "grid '" + name + "' has inconsistent offsets");
        if (uint64_t(endPos) > size)
            damaged(path, "grid '" + name + "' ends at byte " + std::to_string(endPos) + " but the file has " +
                              std::to_string(size) + " bytes");
        if (!in.seek(uint64_t(endPos))) damaged(path, "cannot seek to the end of grid '" + name + "'");
    }
}

// ---------------------------------------------------------------------------------------------
// Grid checks

void checkIndexBox(const int32_t min[3], const int32_t max[3], const char* what)
{
    // Same margins as block_order.cpp: blocks reach 8 voxels below a region, samples 1 voxel above.
    for (int a = 0; a < 3; ++a)
        if (int64_t(min[a]) - 8 < kEdgeKeyCoordMin || int64_t(max[a]) + 1 > kEdgeKeyCoordMax) {
            std::ostringstream s;
            s << what << " [" << min[0] << ", " << min[1] << ", " << min[2] << "] -> [" << max[0] << ", " << max[1]
              << ", " << max[2] << "] lies outside the supported index range [" << kEdgeKeyCoordMin + 8 << ", "
              << kEdgeKeyCoordMax - 1 << "] per axis";
            throw InputError(s.str());
        }
}

void checkGridMetadata(const openvdb::GridBase& meta)
{
    using openvdb::GridBase;
    const auto lo = meta.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MIN);
    const auto hi = meta.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MAX);
    if (!lo || !hi) return;
    const openvdb::Vec3i a = lo->value(), b = hi->value();
    if (a.x() > b.x() || a.y() > b.y() || a.z() > b.z()) return;  // empty grid: reported later, by name
    const int32_t mn[3] = {a.x(), a.y(), a.z()}, mx[3] = {b.x(), b.y(), b.z()};
    checkIndexBox(mn, mx, ("grid '" + meta.getName() + "' has active voxels in the index box").c_str());
}

void checkTransform(const openvdb::math::Transform& xform)
{
    if (!xform.isLinear())
        throw InputError("has a non-linear transform (" + xform.mapType() + "); only linear transforms are supported");
    const openvdb::Mat4d m = xform.baseMap()->getAffineMap()->getMat4();
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c)
            if (!std::isfinite(m(r, c))) throw InputError("has a transform with non-finite coefficients");
    const double det = m.getMat3().det();
    if (!(std::abs(det) >= 1e-300) || !std::isfinite(1.0 / det))
        throw InputError("has a singular transform (not invertible: determinant " + std::to_string(det) + ")");
}

// ---------------------------------------------------------------------------------------------
// Memory

namespace {
// Measured on the bundled volumes (make_volume sphere/noise/gyroid, 256^3): the decimator holds
// about 300 bytes per face of the intermediate mesh (vertices, quadrics, adjacency, queue), and a
// leaf crossed by the surface yields up to ~170 faces of the full-resolution surface (a gyroid
// filling the box; a narrow-band level set yields fewer per leaf).
constexpr double kBytesPerFace = 300.0;
constexpr double kFacesPerLeaf = 170.0;
constexpr uint64_t kBaseBytes = 64ull << 20;
} // namespace

MemoryEstimate estimateMemory(const VolumeInfo& info, const Options& o)
{
    MemoryEstimate e;
    e.base = kBaseBytes;
    e.topology = info.topologyBytes;
    // Live voxels: per slab the layer being extracted and the one above it, every slab running at
    // once (as many cores), plus the seam planes kept for the slabs below (at most a layer in all).
    e.voxels = uint64_t(2 * kPipelineSlabs + 1) * info.maxLeavesPerLayer * 512u * info.valueBytes;
    // 8 candidate blocks per leaf of 12 bytes, doubled for the vector's growth and the sort.
    e.blocks = info.leafCount * 8u * 12u * 2u;
    const double fullFaces = kFacesPerLeaf * double(info.leafCount);
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
                                 uint64_t limit)
{
    const MemoryEstimate e = estimateMemory(info, options);
    if (limit > 0 && e.total() > limit) {
        std::ostringstream s;
        s << path << ": estimated peak memory " << formatBytes(e.total()) << " exceeds the limit of "
          << formatBytes(limit) << " (grid '" << info.gridName << "': " << info.leafCount
          << " leaves; mesh " << formatBytes(e.mesh) << ", topology " << formatBytes(e.topology)
          << "); lower --ratio, --faces or --batch, or raise --max-memory";
        throw InputError(s.str());
    }
    return e;
}

} // namespace vdb_isosimp

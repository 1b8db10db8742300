#include "raw_converter.h"
#include "vdb_isosimp/temporary_file.h"

#include <openvdb/io/Archive.h>
#include <openvdb/io/File.h>
#include <openvdb/tools/Prune.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <sys/stat.h>
#include <sys/resource.h>
#include <type_traits>
#include <unistd.h>
#include <vector>

namespace vdb_isosimp {

namespace {

using FloatTree = openvdb::FloatTree;
using LeafT = FloatTree::LeafNodeType;
constexpr int kLeafDim = LeafT::DIM;  // 8

/// How values become grid values and what counts as background.
struct ValueRules {
    bool scaled = false;
    double scale = 1, intercept = 0;
    bool clamped = false;
    double lo = 0, hi = 0;
    float background = 0;
    double tolerance = 0;
    bool levelSet = false;
};

template <typename T, bool Swap>
inline T loadValue(const unsigned char* p)
{
    if constexpr (sizeof(T) == 1) {
        T v;
        std::memcpy(&v, p, 1);
        return v;
    } else {
        unsigned char b[sizeof(T)];
        std::memcpy(b, p, sizeof(T));
        if constexpr (Swap) std::reverse(b, b + sizeof(T));
        T v;
        std::memcpy(&v, b, sizeof(T));
        return v;
    }
}

enum class LeafKind { Empty, ActiveTile, InactiveTile, Leaf };

struct LeafResult {
    LeafKind kind = LeafKind::Empty;
    float value = 0;
    std::unique_ptr<LeafT> leaf;
};

struct SlabGeometry {
    uint64_t X, Y;
    int z0;       // first z of the slab
    int nz;       // z rows in the slab (8 except maybe the last)
    int leavesX;  // ceil(X/8)
};

/// Byte offset of voxel (x0, y, z) of a slab.
inline uint64_t rowOffset(const SlabGeometry& g, int x0, int y, int z, std::size_t size)
{
    return ((static_cast<uint64_t>(z) * g.Y + static_cast<uint64_t>(y)) * g.X + static_cast<uint64_t>(x0)) * size;
}

/// The common case (fog volume, no scaling, no clamping, zero tolerance): a leaf is uniform when
/// every stored value has the same bytes as its first one, which a row-wise memcmp decides without
/// converting anything; only mixed leaves are converted, straight into the leaf buffer.
template <typename T, bool Swap>
void convertLeafPlain(const unsigned char* slab, const SlabGeometry& g, int bx, int by, const ValueRules& r, LeafResult& out)
{
    const int x0 = bx * kLeafDim, y0 = by * kLeafDim;
    const int nx = static_cast<int>(std::min<uint64_t>(kLeafDim, g.X - static_cast<uint64_t>(x0)));
    const int ny = static_cast<int>(std::min<uint64_t>(kLeafDim, g.Y - static_cast<uint64_t>(y0)));
    const bool whole = nx == kLeafDim && ny == kLeafDim && g.nz == kLeafDim;
    const unsigned char* first = slab + rowOffset(g, x0, y0, 0, sizeof(T));
    unsigned char pattern[kLeafDim * sizeof(T)];
    for (int x = 0; x < kLeafDim; ++x) std::memcpy(pattern + x * sizeof(T), first, sizeof(T));
    bool uniform = true;
    for (int z = 0; z < g.nz && uniform; ++z)
        for (int y = 0; y < ny && uniform; ++y) {
            const unsigned char* row = slab + rowOffset(g, x0, y0 + y, z, sizeof(T));
            uniform = whole ? std::memcmp(row, pattern, sizeof pattern) == 0 : std::memcmp(row, pattern, nx * sizeof(T)) == 0;
        }
    const float bg = r.background;
    if (uniform) {
        const float v = static_cast<float>(loadValue<T, Swap>(first));
        if (v == bg) { out.kind = LeafKind::Empty; return; }
        if (whole && v == v) { out.kind = LeafKind::ActiveTile; out.value = v; return; }
    }
    out.kind = LeafKind::Leaf;
    out.leaf = std::make_unique<LeafT>(openvdb::Coord(x0, y0, g.z0), bg, false);
    float* data = out.leaf->buffer().data();
    auto& mask = out.leaf->getValueMask();
    for (int z = 0; z < g.nz; ++z)
        for (int y = 0; y < ny; ++y) {
            const unsigned char* row = slab + rowOffset(g, x0, y0 + y, z, sizeof(T));
            const int base = (y << 3) | z;
            for (int x = 0; x < nx; ++x) {
                const float v = static_cast<float>(loadValue<T, Swap>(row + x * sizeof(T)));
                const int i = (x << 6) | base;
                if (v != bg) {  // NaN included: kept, active
                    data[i] = v;
                    mask.setOn(static_cast<openvdb::Index>(i));
                }
            }
        }
}

/// Any rules: scaling, clamping, tolerance, level sets.
template <typename T, bool Swap>
void convertLeafGeneral(const unsigned char* slab, const SlabGeometry& g, int bx, int by, const ValueRules& r, LeafResult& out)
{
    const int x0 = bx * kLeafDim, y0 = by * kLeafDim;
    const int nx = static_cast<int>(std::min<uint64_t>(kLeafDim, g.X - static_cast<uint64_t>(x0)));
    const int ny = static_cast<int>(std::min<uint64_t>(kLeafDim, g.Y - static_cast<uint64_t>(y0)));
    const bool whole = nx == kLeafDim && ny == kLeafDim && g.nz == kLeafDim;

    float vals[LeafT::SIZE];
    float vmin = std::numeric_limits<float>::infinity(), vmax = -vmin;
    bool hasNaN = false;
    int nearBg = 0, inside = 0;  // fog: |v-bg|<=tol ; level set: outside (>= bg-tol) / inside (<= -bg+tol)
    const double bg = r.background, tol = r.tolerance;
    for (int z = 0; z < g.nz; ++z) {
        for (int y = 0; y < ny; ++y) {
            const unsigned char* row = slab + rowOffset(g, x0, y0 + y, z, sizeof(T));
            float* dst = vals + ((y << 3) | z);
            for (int x = 0; x < nx; ++x) {
                double d = static_cast<double>(loadValue<T, Swap>(row + x * sizeof(T)));
                if (r.scaled) d = d * r.scale + r.intercept;
                if (r.clamped) d = std::min(std::max(d, r.lo), r.hi);
                const float v = static_cast<float>(d);
                dst[x << 6] = v;
                if (v != v) { hasNaN = true; continue; }
                vmin = std::min(vmin, v);
                vmax = std::max(vmax, v);
                if (!r.levelSet) {
                    nearBg += std::fabs(static_cast<double>(v) - bg) <= tol;
                } else {
                    nearBg += static_cast<double>(v) >= bg - tol;
                    inside += static_cast<double>(v) <= -bg + tol;
                }
            }
        }
    }
    const int count = nx * ny * g.nz;
    if (!hasNaN) {
        if (nearBg == count) { out.kind = LeafKind::Empty; return; }
        if (whole && inside == count) { out.kind = LeafKind::InactiveTile; out.value = -r.background; return; }
        if (whole && static_cast<double>(vmax) - static_cast<double>(vmin) <= 2 * tol && nearBg == 0 && inside == 0) {
            out.kind = LeafKind::ActiveTile;
            out.value = tol == 0 ? vmin : static_cast<float>(0.5 * (static_cast<double>(vmin) + static_cast<double>(vmax)));
            return;
        }
    }
    out.kind = LeafKind::Leaf;
    out.leaf = std::make_unique<LeafT>(openvdb::Coord(x0, y0, g.z0), r.background, false);
    float* data = out.leaf->buffer().data();
    auto& mask = out.leaf->getValueMask();
    for (int x = 0; x < nx; ++x) {
        for (int y = 0; y < ny; ++y) {
            const int base = (x << 6) | (y << 3);
            for (int z = 0; z < g.nz; ++z) {
                const float v = vals[base | z];
                const double d = v;
                bool active;
                float stored = v;
                if (!r.levelSet) {
                    active = !(std::fabs(d - bg) <= tol);
                    if (!active) stored = r.background;
                } else if (d >= bg - tol) {
                    active = false;
                    stored = r.background;
                } else if (d <= -bg + tol) {
                    active = false;
                    stored = -r.background;
                } else {
                    active = true;
                }
                data[base | z] = stored;
                if (active) mask.setOn(static_cast<openvdb::Index>(base | z));
            }
        }
    }
}

using LeafFn = void (*)(const unsigned char*, const SlabGeometry&, int, int, const ValueRules&, LeafResult&);

template <typename T>
LeafFn pickFn(bool swap, bool plain)
{
    if (sizeof(T) == 1) swap = false;
    if (plain) return swap ? &convertLeafPlain<T, true> : &convertLeafPlain<T, false>;
    return swap ? &convertLeafGeneral<T, true> : &convertLeafGeneral<T, false>;
}

LeafFn leafFunction(ScalarType t, bool swap, bool plain)
{
    switch (t) {
    case ScalarType::U8: return pickFn<uint8_t>(swap, plain);
    case ScalarType::I8: return pickFn<int8_t>(swap, plain);
    case ScalarType::U16: return pickFn<uint16_t>(swap, plain);
    case ScalarType::I16: return pickFn<int16_t>(swap, plain);
    case ScalarType::U32: return pickFn<uint32_t>(swap, plain);
    case ScalarType::I32: return pickFn<int32_t>(swap, plain);
    case ScalarType::F32: return pickFn<float>(swap, plain);
    case ScalarType::F64: return pickFn<double>(swap, plain);
    }
    return nullptr;
}

/// openvdb::io::File::write never looks at its stream after writing, so a full disk leaves a
/// truncated file that looks complete. This writes the same seekable layout (header, grid offsets,
/// delayed-loadable grids) to a stream of ours, whose state is checked.
class CheckedArchive : public openvdb::io::Archive {
public:
    void writeTo(std::ostream& os, const openvdb::GridCPtrVec& grids) const { Archive::write(os, grids, /*seekable=*/true); }
};

/// Removes a file on scope exit unless released.
struct TempFileGuard {
    std::string path;
    bool armed = true;
    ~TempFileGuard()
    {
        if (armed && !path.empty()) std::remove(path.c_str());
    }
};

} // namespace

uint64_t peakRssBytes()
{
    struct rusage ru {};
    if (getrusage(RUSAGE_SELF, &ru) != 0) return 0;
    return static_cast<uint64_t>(ru.ru_maxrss) * 1024u;  // Linux: kilobytes
}

namespace {

/// Where the voxels come from: a file read as one byte stream (raw, NRRD, MetaImage, NIfTI), or an image
/// stack read slice by slice (DICOM series, TIFF stack).
struct OpenedVolume {
    RawVolumeInfo info;
    std::unique_ptr<SliceSource> slices;
};

void applyOverrides(const std::string& input, const RawConvertOptions& options, RawVolumeInfo& info)
{
    if (options.spacing) {
        for (int i = 0; i < 3; ++i)
            if (!((*options.spacing)[i] > 0) || !std::isfinite((*options.spacing)[i]))
                throw RawInputError(input, "invalid --spacing: every value must be positive");
        info.spacing = *options.spacing;
    }
    if (options.origin) {
        for (int i = 0; i < 3; ++i)
            if (!std::isfinite((*options.origin)[i])) throw RawInputError(input, "invalid --origin: not finite");
        info.origin = *options.origin;
    }
    // Image stacks may state no pixel size at all (a DICOM series without PixelSpacing).
    for (int i = 0; i < 3; ++i)
        if (!(info.spacing[i] > 0) || !std::isfinite(info.spacing[i]))
            throw RawInputError(input, "no valid voxel size in the files (PixelSpacing?): give --spacing X,Y,Z");
}

OpenedVolume openVolume(const std::string& input, const RawConvertOptions& options)
{
    OpenedVolume v;
    if (isSliceStackInput(input)) {
        SliceSourceOptions so;
        so.series = options.series;
        v.slices = openSliceSource(input, so);
        v.info = v.slices->info();
    } else {
        if (!options.series.empty()) throw RawInputError(input, "--series applies to a folder of DICOM files");
        v.info = readVolumeInfo(input, options.layout);
    }
    applyOverrides(input, options, v.info);
    return v;
}

openvdb::FloatGrid::Ptr convertOpened(const std::string& input, OpenedVolume& volume, const RawConvertOptions& options,
                                      RawConvertStats* stats, std::chrono::steady_clock::time_point start);

} // namespace

RawVolumeInfo resolveVolumeInfo(const std::string& input, const RawConvertOptions& options)
{
    return openVolume(input, options).info;
}

openvdb::math::Transform::Ptr makeTransform(const RawVolumeInfo& info)
{
    // OpenVDB multiplies row vectors: world = [i j k 1] * M.
    openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
    for (int axis = 0; axis < 3; ++axis)
        for (int w = 0; w < 3; ++w) m[axis][w] = info.direction[w][axis] * info.spacing[axis];
    for (int w = 0; w < 3; ++w) m[3][w] = info.origin[w];
    try {
        return openvdb::math::Transform::createLinearTransform(m);
    } catch (const openvdb::Exception& e) {
        // OpenVDB refuses maps it considers singular (|det| below ~1e-15: e.g. voxels under 1e-5).
        throw RawInputError(info.headerFile, std::string("voxel spacing and directions OpenVDB cannot represent (") + e.what() + ")");
    }
}

openvdb::FloatGrid::Ptr convertToGrid(const std::string& input, const RawConvertOptions& options, RawConvertStats* stats)
{
    const auto start = std::chrono::steady_clock::now();
    OpenedVolume volume = openVolume(input, options);
    return convertOpened(input, volume, options, stats, start);
}

namespace {

openvdb::FloatGrid::Ptr convertOpened(const std::string& input, OpenedVolume& volume, const RawConvertOptions& options,
                                      RawConvertStats* stats, std::chrono::steady_clock::time_point start)
{
    openvdb::initialize();
    const RawVolumeInfo& info = volume.info;

    ValueRules rules;
    rules.levelSet = options.gridClass == RawGridClass::LevelSet;
    if (info.scale != 1.0 || info.intercept != 0.0) {
        rules.scaled = true;
        rules.scale = info.scale;
        rules.intercept = info.intercept;
    }
    if (options.clamp) {
        rules.clamped = true;
        rules.lo = (*options.clamp)[0];
        rules.hi = (*options.clamp)[1];
        if (!(rules.lo <= rules.hi)) throw RawInputError(input, "invalid --clamp: LO must not exceed HI");
    }
    if (!(options.tolerance >= 0) || !std::isfinite(options.tolerance)) throw RawInputError(input, "invalid --tolerance: must be >= 0");
    rules.tolerance = options.tolerance;
    double background = 0;
    if (options.background) background = *options.background;
    else if (rules.levelSet) background = 3.0 * std::min({info.spacing[0], info.spacing[1], info.spacing[2]});
    if (!std::isfinite(background)) throw RawInputError(input, "invalid --background: not finite");
    if (rules.levelSet && !(background > 0)) throw RawInputError(input, "invalid --background for a level set: must be positive");
    rules.background = static_cast<float>(background);

    auto grid = openvdb::FloatGrid::create(rules.background);
    grid->setTransform(makeTransform(info));
    grid->setName(!options.name.empty() ? options.name : (rules.levelSet ? "surface" : "density"));
    grid->setGridClass(rules.levelSet ? openvdb::GRID_LEVEL_SET : openvdb::GRID_FOG_VOLUME);
    FloatTree& tree = grid->tree();

    const std::size_t vsize = scalarSize(info.type);
    const uint64_t X = info.dims[0], Y = info.dims[1], Z = info.dims[2];
    const uint64_t slabCount = (Z + kLeafDim - 1) / kLeafDim;
    const int leavesX = static_cast<int>((X + kLeafDim - 1) / kLeafDim);
    const int leavesY = static_cast<int>((Y + kLeafDim - 1) / kLeafDim);
    const std::size_t leavesPerSlab = static_cast<std::size_t>(leavesX) * static_cast<std::size_t>(leavesY);
    const bool plain = !rules.levelSet && !rules.scaled && !rules.clamped && rules.tolerance == 0;
    const LeafFn leafFn = leafFunction(info.type, vsize > 1 && info.byteOrder != hostByteOrder(), plain);

    std::unique_ptr<DataStream> stream;
    if (!volume.slices) {
        stream = std::make_unique<DataStream>(info.dataFile, info.fileOffset, info.encoding, info.decodedSkip + info.dataBytes());
        stream->skip(info.decodedSkip);
    }

    const std::size_t tokens = static_cast<std::size_t>(std::max(1, options.readAhead) + 1);
    std::vector<std::vector<unsigned char>> buffers(std::min<uint64_t>(tokens, slabCount));
    std::vector<LeafResult> results(leavesPerSlab);
    uint64_t nextRead = 0;

    struct SlabToken {
        uint64_t index;
        std::vector<unsigned char>* data;
    };

    tbb::parallel_pipeline(
        tokens,
        tbb::make_filter<void, SlabToken>(
            tbb::filter_mode::serial_in_order,
            [&](tbb::flow_control& fc) -> SlabToken {
                if (nextRead >= slabCount) {
                    fc.stop();
                    return {};
                }
                const uint64_t s = nextRead++;
                auto& buf = buffers[s % buffers.size()];
                const uint64_t rows = std::min<uint64_t>(kLeafDim, Z - s * kLeafDim);
                const uint64_t bytes = X * Y * rows * vsize;
                if (buf.size() < bytes) buf.resize(static_cast<std::size_t>(bytes));
                if (volume.slices) volume.slices->readSlices(s * kLeafDim, rows, buf.data());
                else stream->readExact(buf.data(), static_cast<std::size_t>(bytes));
                return {s, &buf};
            }) &
            tbb::make_filter<SlabToken, void>(
                tbb::filter_mode::serial_in_order,
                [&](SlabToken tok) {
                    SlabGeometry g;
                    g.X = X;
                    g.Y = Y;
                    g.z0 = static_cast<int>(tok.index * kLeafDim);
                    g.nz = static_cast<int>(std::min<uint64_t>(kLeafDim, Z - tok.index * kLeafDim));
                    g.leavesX = leavesX;
                    const unsigned char* slab = tok.data->data();
                    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leavesPerSlab, 16), [&](const tbb::blocked_range<std::size_t>& range) {
                        for (std::size_t i = range.begin(); i < range.end(); ++i) {
                            results[i] = LeafResult{};
                            leafFn(slab, g, static_cast<int>(i % static_cast<std::size_t>(leavesX)),
                                   static_cast<int>(i / static_cast<std::size_t>(leavesX)), rules, results[i]);
                        }
                    });
                    for (std::size_t i = 0; i < leavesPerSlab; ++i) {
                        LeafResult& res = results[i];
                        const openvdb::Coord xyz(static_cast<int>(i % static_cast<std::size_t>(leavesX)) * kLeafDim,
                                                 static_cast<int>(i / static_cast<std::size_t>(leavesX)) * kLeafDim, g.z0);
                        switch (res.kind) {
                        case LeafKind::Empty: break;
                        case LeafKind::ActiveTile: tree.addTile(1, xyz, res.value, true); break;
                        case LeafKind::InactiveTile: tree.addTile(1, xyz, res.value, false); break;
                        case LeafKind::Leaf: tree.addLeaf(res.leaf.release()); break;
                        }
                    }
                    if (options.progress) options.progress(tok.index + 1, slabCount);
                }));

    buffers.clear();
    buffers.shrink_to_fit();
    openvdb::tools::prune(tree, 0.0f);

    if (stats) {
        stats->info = info;
        stats->source = volume.slices ? volume.slices->describe() : std::string();
        stats->activeVoxels = tree.activeVoxelCount();
        stats->leafCount = tree.leafCount();
        stats->tileCount = tree.activeTileCount();
        stats->inputBytes = info.dataBytes();
        stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        stats->peakRssBytes = peakRssBytes();
    }
    return grid;
}

} // namespace

RawConvertStats convertRawToVdb(const std::string& input, const std::string& output, const RawConvertOptions& options)
{
    const auto start = std::chrono::steady_clock::now();
    // Header first (every slice's, for an image stack): a bad input is reported before anything is created.
    OpenedVolume volume = openVolume(input, options);

    // A .vdb needs a seekable regular file; renaming a temporary file over a device would replace it.
    struct stat st {};
    if (::stat(output.c_str(), &st) == 0) {
        if (S_ISDIR(st.st_mode)) throw RawInputError(output, "cannot write: is a directory");
        if (!S_ISREG(st.st_mode)) throw RawInputError(output, "cannot write: not a regular file (a .vdb file must be seekable)");
    }

    TempFileGuard guard;
    guard.path = temporaryPathFor(output);
    {
        FILE* f = std::fopen(guard.path.c_str(), "wb");
        if (!f) {
            const std::string err = std::strerror(errno);
            guard.armed = false;  // nothing was created
            throw RawInputError(output, "cannot write: " + err);
        }
        std::fclose(f);
    }

    RawConvertStats stats;
    auto grid = convertOpened(input, volume, options, &stats, start);
    grid->setSaveFloatAsHalf(options.half);
    try {
        std::ofstream os(guard.path, std::ios::out | std::ios::binary | std::ios::trunc);
        if (!os) throw RawInputError(output, std::string("cannot write: ") + std::strerror(errno));
        errno = 0;
        CheckedArchive().writeTo(os, openvdb::GridCPtrVec{grid});
        os.flush();
        const int err = errno;
        if (!os) throw RawInputError(output, std::string("cannot write: ") + (err ? std::strerror(err) : "write error"));
        os.close();
        if (!os) throw RawInputError(output, std::string("cannot write: ") + (errno ? std::strerror(errno) : "write error"));
    } catch (const RawInputError&) {
        throw;
    } catch (const openvdb::Exception& e) {
        throw RawInputError(output, std::string("cannot write: ") + e.what());
    } catch (const std::exception& e) {
        throw RawInputError(output, std::string("cannot write: ") + e.what());
    }
    if (std::rename(guard.path.c_str(), output.c_str()) != 0)
        throw RawInputError(output, std::string("cannot rename the finished file into place: ") + std::strerror(errno));
    guard.armed = false;
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    stats.peakRssBytes = peakRssBytes();
    return stats;
}

} // namespace vdb_isosimp

// Tests of the dense-volume converter (raw2vdb): header parsing, streaming conversion, the program's
// behaviour on good and bad input. Every fixture is written here from a known formula.
#include "program_runs.h"
#include "raw_converter.h"
#include "raw_header.h"

#include <gtest/gtest.h>
#include <openvdb/io/File.h>
#include <openvdb/math/Half.h>
#include <zlib.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace vdb_isosimp;
using namespace vdb_isosimp::testing;

namespace {

constexpr int NX = 20, NY = 17, NZ = 13;
const std::array<uint64_t, 3> kDims{{NX, NY, NZ}};
const ScalarType kAllTypes[] = {ScalarType::U8, ScalarType::I8, ScalarType::U16, ScalarType::I16,
                                ScalarType::U32, ScalarType::I32, ScalarType::F32, ScalarType::F64};

/// The test volume: background (0) for x >= 16 and in the whole leaf at (8,8,0), the constant 42 in
/// the first 8x8x8 block (one whole leaf), the constant 7 in the last y row (partial leaves, which must not grow into tiles), elsewhere
/// a pattern spanning the type's range that also hits 0 now and then.
double formula(int x, int y, int z, ScalarType t)
{
    if (x >= 16) return 0;
    if (x < 8 && y < 8 && z < 8) return 42;
    if (x >= 8 && y >= 8 && y < 16 && z < 8) return 0;
    if (y == NY - 1) return 7;
    const int p = (x * 3 + y * 5 + z * 7) % 97;  // 0..96
    switch (t) {
    case ScalarType::U8: return p + (p > 50 ? 150 : 0);
    case ScalarType::I8: return p - 48;
    case ScalarType::U16: return p * 601.0;
    case ScalarType::I16: return (p - 48) * 601.0;
    case ScalarType::U32: return p * 170000.0;       // < 2^24: exact in float
    case ScalarType::I32: return (p - 48) * 340000.0;
    case ScalarType::F32: return static_cast<float>((p - 48) * 0.37);
    case ScalarType::F64: return (p - 48) * 0.37 + 1e-9;
    }
    return 0;
}

float expected(int x, int y, int z, ScalarType t) { return static_cast<float>(formula(x, y, z, t)); }

template <typename T>
void putValue(std::string& out, double v, ByteOrder bo)
{
    T t = static_cast<T>(v);
    unsigned char b[sizeof(T)];
    std::memcpy(b, &t, sizeof(T));
    if (bo != hostByteOrder()) std::reverse(b, b + sizeof(T));
    out.append(reinterpret_cast<const char*>(b), sizeof(T));
}

void putAny(std::string& out, ScalarType t, double v, ByteOrder bo)
{
    switch (t) {
    case ScalarType::U8: putValue<uint8_t>(out, v, bo); break;
    case ScalarType::I8: putValue<int8_t>(out, v, bo); break;
    case ScalarType::U16: putValue<uint16_t>(out, v, bo); break;
    case ScalarType::I16: putValue<int16_t>(out, v, bo); break;
    case ScalarType::U32: putValue<uint32_t>(out, v, bo); break;
    case ScalarType::I32: putValue<int32_t>(out, v, bo); break;
    case ScalarType::F32: putValue<float>(out, v, bo); break;
    case ScalarType::F64: putValue<double>(out, v, bo); break;
    }
}

using Formula = std::function<double(int, int, int)>;

std::string volumeBytes(ScalarType t, ByteOrder bo, const std::array<uint64_t, 3>& dims, const Formula& f)
{
    std::string out;
    out.reserve(dims[0] * dims[1] * dims[2] * scalarSize(t));
    for (uint64_t z = 0; z < dims[2]; ++z)
        for (uint64_t y = 0; y < dims[1]; ++y)
            for (uint64_t x = 0; x < dims[0]; ++x) putAny(out, t, f(int(x), int(y), int(z)), bo);
    return out;
}

std::string volumeBytes(ScalarType t, ByteOrder bo)
{
    return volumeBytes(t, bo, kDims, [t](int x, int y, int z) { return formula(x, y, z, t); });
}

/// gzip (windowBits 15+16) or zlib (15) compression.
std::string deflateBytes(const std::string& in, bool gzip)
{
    z_stream zs{};
    EXPECT_EQ(deflateInit2(&zs, 6, Z_DEFLATED, gzip ? 15 + 16 : 15, 8, Z_DEFAULT_STRATEGY), Z_OK);
    std::string out(deflateBound(&zs, in.size()) + 64, '\0');
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
    zs.avail_in = static_cast<uInt>(in.size());
    zs.next_out = reinterpret_cast<Bytef*>(&out[0]);
    zs.avail_out = static_cast<uInt>(out.size());
    EXPECT_EQ(deflate(&zs, Z_FINISH), Z_STREAM_END);
    out.resize(zs.total_out);
    deflateEnd(&zs);
    return out;
}

const char* nrrdType(ScalarType t)
{
    switch (t) {
    case ScalarType::U8: return "uchar";
    case ScalarType::I8: return "signed char";
    case ScalarType::U16: return "ushort";
    case ScalarType::I16: return "short";
    case ScalarType::U32: return "uint";
    case ScalarType::I32: return "int";
    case ScalarType::F32: return "float";
    case ScalarType::F64: return "double";
    }
    return "";
}

const char* metaType(ScalarType t)
{
    switch (t) {
    case ScalarType::U8: return "MET_UCHAR";
    case ScalarType::I8: return "MET_CHAR";
    case ScalarType::U16: return "MET_USHORT";
    case ScalarType::I16: return "MET_SHORT";
    case ScalarType::U32: return "MET_UINT";
    case ScalarType::I32: return "MET_INT";
    case ScalarType::F32: return "MET_FLOAT";
    case ScalarType::F64: return "MET_DOUBLE";
    }
    return "";
}

int niftiType(ScalarType t)
{
    switch (t) {
    case ScalarType::U8: return 2;
    case ScalarType::I8: return 256;
    case ScalarType::U16: return 512;
    case ScalarType::I16: return 4;
    case ScalarType::U32: return 768;
    case ScalarType::I32: return 8;
    case ScalarType::F32: return 16;
    case ScalarType::F64: return 64;
    }
    return 0;
}

/// Geometry shared by the fixtures: axis step vectors (columns) and the centre of voxel 0.
struct Geometry {
    std::array<std::array<double, 3>, 3> axes{{{{0.5, 0, 0}}, {{0, 0.75, 0}}, {{0, 0, 1.25}}}};
    std::array<double, 3> origin{{10, -5, 3}};
};

std::string vec3(const std::array<double, 3>& v)
{
    std::ostringstream s;
    s.precision(17);
    s << "(" << v[0] << "," << v[1] << "," << v[2] << ")";
    return s.str();
}

std::string nrrdHeader(ScalarType t, ByteOrder bo, const std::string& encoding, const Geometry& g, const std::string& dataFile = "")
{
    std::ostringstream h;
    h << "NRRD0004\n# written by test_raw2vdb\ntype: " << nrrdType(t) << "\ndimension: 3\nsizes: " << NX << " " << NY << " " << NZ
      << "\nendian: " << byteOrderName(bo) << "\nencoding: " << encoding << "\nspace: left-posterior-superior\n"
      << "space directions: " << vec3(g.axes[0]) << " " << vec3(g.axes[1]) << " " << vec3(g.axes[2]) << "\n"
      << "kinds: domain domain domain\nspace origin: " << vec3(g.origin) << "\nsome key:=some value\n";
    if (!dataFile.empty()) h << "data file: " << dataFile << "\n";
    else h << "\n";
    return h.str();
}

std::string metaHeader(ScalarType t, ByteOrder bo, bool compressed, const Geometry& g, const std::string& dataFile)
{
    std::ostringstream h;
    h.precision(17);
    std::array<double, 3> sp;
    for (int c = 0; c < 3; ++c) sp[c] = std::sqrt(g.axes[c][0] * g.axes[c][0] + g.axes[c][1] * g.axes[c][1] + g.axes[c][2] * g.axes[c][2]);
    h << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = " << (bo == ByteOrder::Big ? "True" : "False")
      << "\nCompressedData = " << (compressed ? "True" : "False") << "\nTransformMatrix =";
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) h << " " << g.axes[c][r] / sp[c];
    h << "\nOffset = " << g.origin[0] << " " << g.origin[1] << " " << g.origin[2] << "\nCenterOfRotation = 0 0 0\n"
      << "AnatomicalOrientation = RAI\nElementSpacing = " << sp[0] << " " << sp[1] << " " << sp[2] << "\nDimSize = " << NX << " " << NY
      << " " << NZ << "\nElementType = " << metaType(t) << "\nElementDataFile = " << dataFile << "\n";
    return h.str();
}

struct NiftiFields {
    int qformCode = 0, sformCode = 1;
    float quatern[3] = {0, 0, 0};
    float qoffset[3] = {0, 0, 0};
    float qfac = 1;
    float slope = 0, inter = 0;
    int16_t dims[8] = {3, NX, NY, NZ, 1, 1, 1, 1};
};

/// A NIfTI-1 single file (.nii): 348-byte header, 4 bytes of extension flag, the data.
std::string niftiBytes(ScalarType t, ByteOrder bo, const Geometry& g, const NiftiFields& nf, const std::string& data)
{
    std::string h(352, '\0');
    auto put = [&](std::size_t off, auto v) {
        unsigned char b[sizeof(v)];
        std::memcpy(b, &v, sizeof(v));
        if (bo != hostByteOrder()) std::reverse(b, b + sizeof(v));
        std::memcpy(&h[off], b, sizeof(v));
    };
    put(0, int32_t(348));
    for (int i = 0; i < 8; ++i) put(40 + 2 * i, nf.dims[i]);
    put(70, int16_t(niftiType(t)));
    put(72, int16_t(8 * scalarSize(t)));
    std::array<double, 3> sp;
    for (int c = 0; c < 3; ++c) sp[c] = std::sqrt(g.axes[c][0] * g.axes[c][0] + g.axes[c][1] * g.axes[c][1] + g.axes[c][2] * g.axes[c][2]);
    put(76, nf.qfac);
    for (int i = 0; i < 3; ++i) put(80 + 4 * i, float(sp[i]));
    put(108, 352.0f);
    put(112, nf.slope);
    put(116, nf.inter);
    put(252, int16_t(nf.qformCode));
    put(254, int16_t(nf.sformCode));
    for (int i = 0; i < 3; ++i) put(256 + 4 * i, nf.quatern[i]);
    for (int i = 0; i < 3; ++i) put(268 + 4 * i, nf.qoffset[i]);
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) put(280 + 16 * r + 4 * c, float(g.axes[c][r]));
        put(280 + 16 * r + 12, float(g.origin[r]));
    }
    std::memcpy(&h[344], "n+1\0", 4);
    return h + data;
}

std::vector<std::string> listDir(const fs::path& dir)
{
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}


/// Every voxel of the volume equals `value(x,y,z)` (exactly, or within `tol`) and is active iff it
/// differs from the background 0; nothing outside the volume is active.
void expectVolume(const openvdb::FloatGrid& grid, const std::array<uint64_t, 3>& dims, const std::function<float(int, int, int)>& value,
                  float tol = 0.0f, float background = 0.0f)
{
    auto acc = grid.getConstAccessor();
    uint64_t active = 0;
    int bad = 0;
    for (int z = 0; z < int(dims[2]); ++z)
        for (int y = 0; y < int(dims[1]); ++y)
            for (int x = 0; x < int(dims[0]); ++x) {
                const openvdb::Coord ijk(x, y, z);
                const float want = value(x, y, z);
                const float got = acc.getValue(ijk);
                const bool on = want != background;
                active += on;
                const bool ok = tol == 0 ? got == want : std::fabs(got - want) <= tol;
                if ((!ok || acc.isValueOn(ijk) != on) && bad++ < 5)
                    ADD_FAILURE() << "voxel " << ijk << ": got " << got << (acc.isValueOn(ijk) ? " (on)" : " (off)") << ", expected " << want;
            }
    EXPECT_EQ(grid.activeVoxelCount(), active);
    const auto bbox = grid.evalActiveVoxelBoundingBox();
    if (active > 0) {
        EXPECT_GE(bbox.min().x(), 0);
        EXPECT_GE(bbox.min().y(), 0);
        EXPECT_GE(bbox.min().z(), 0);
        EXPECT_LT(bbox.max().x(), int(dims[0]));
        EXPECT_LT(bbox.max().y(), int(dims[1]));
        EXPECT_LT(bbox.max().z(), int(dims[2]));
    }
}

void expectTransform(const openvdb::math::Transform& got, const Geometry& g, double tol = 1e-9)
{
    const openvdb::Vec3d pts[] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {19, 16, 12}, {3.5, -2, 7.25}};
    for (const auto& p : pts) {
        openvdb::Vec3d want(g.origin[0], g.origin[1], g.origin[2]);
        for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r) want[r] += g.axes[c][r] * p[c];
        const auto w = got.indexToWorld(p);
        for (int r = 0; r < 3; ++r) EXPECT_NEAR(w[r], want[r], tol) << "index " << p << " -> " << w << ", expected " << want;
    }
}

RawConvertOptions rawOptions(ScalarType t, ByteOrder bo)
{
    RawConvertOptions o;
    o.layout.dims = kDims;
    o.layout.type = t;
    o.layout.byteOrder = bo;
    return o;
}

} // namespace

// ---------------------------------------------------------------------------------------------
// Acceptance 1: every type, both byte orders, through the library and the written file.

TEST(RoundTrip, EveryTypeBothByteOrdersLibraryAndFile)
{
    TempDir dir;
    for (ScalarType t : kAllTypes) {
        for (ByteOrder bo : {ByteOrder::Little, ByteOrder::Big}) {
            SCOPED_TRACE(std::string(scalarName(t)) + " " + byteOrderName(bo));
            const fs::path raw = dir / (std::string("vol_") + scalarName(t) + "_" + byteOrderName(bo) + ".raw");
            writeFile(raw, volumeBytes(t, bo));
            const auto expect = [t](int x, int y, int z) { return expected(x, y, z, t); };

            RawConvertStats stats;
            auto grid = convertToGrid(raw.string(), rawOptions(t, bo), &stats);
            ASSERT_TRUE(grid);
            expectVolume(*grid, kDims, expect);
            EXPECT_EQ(stats.info.type, t);
            EXPECT_EQ(stats.inputBytes, uint64_t(NX) * NY * NZ * scalarSize(t));
            // The constant 42 block is one whole leaf: it must be a tile, not a leaf node.
            EXPECT_EQ(grid->tree().probeConstLeaf(openvdb::Coord(0, 0, 0)), nullptr);
            EXPECT_TRUE(grid->tree().isValueOn(openvdb::Coord(3, 3, 3)));
            EXPECT_GE(stats.tileCount, 1u);
            // The all-background leaf at (8,8,0) adds nothing.
            EXPECT_EQ(grid->tree().probeConstLeaf(openvdb::Coord(8, 8, 0)), nullptr);
            EXPECT_FALSE(grid->tree().isValueOn(openvdb::Coord(12, 12, 4)));

            const fs::path vdb = dir / (raw.stem().string() + ".vdb");
            convertRawToVdb(raw.string(), vdb.string(), rawOptions(t, bo));
            auto back = readVdb(vdb);
            ASSERT_TRUE(back);
            expectVolume(*back, kDims, expect);
            EXPECT_EQ(back->getName(), "density");
            EXPECT_EQ(back->getGridClass(), openvdb::GRID_FOG_VOLUME);
        }
    }
}

TEST(RoundTrip, ThroughTheProgramBigEndian)
{
    TempDir dir;
    for (ScalarType t : {ScalarType::U16, ScalarType::I32, ScalarType::F64}) {
        SCOPED_TRACE(scalarName(t));
        const fs::path raw = dir / "vol.raw", vdb = dir / "vol.vdb";
        writeFile(raw, volumeBytes(t, ByteOrder::Big));
        const auto r = raw2vdb({raw.string(), "-o", vdb.string(), "--dims", "20,17,13", "--type", scalarName(t), "--endian", "big",
                                "--spacing", "0.5,0.75,1.25", "--origin", "10,-5,3"},
                               dir.path);
        ASSERT_EQ(r.code, 0) << r.err;
        EXPECT_TRUE(r.err.empty()) << r.err;  // no progress bar when stderr is not a terminal
        // one summary line: dims, type, active voxels, leaves, tiles, seconds, peak memory
        EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
        EXPECT_NE(r.out.find("20x17x13"), std::string::npos) << r.out;
        EXPECT_NE(r.out.find(scalarName(t)), std::string::npos) << r.out;
        for (const char* word : {"active voxels", "leaves", "tiles", " s,", "peak"}) EXPECT_NE(r.out.find(word), std::string::npos) << r.out;
        auto grid = readVdb(vdb);
        ASSERT_TRUE(grid);
        expectVolume(*grid, kDims, [t](int x, int y, int z) { return expected(x, y, z, t); });
        expectTransform(grid->transform(), Geometry{});
        EXPECT_EQ(listDir(dir.path), (std::vector<std::string>{"vol.raw", "vol.vdb"}));
    }
}

TEST(RoundTrip, HalfPrecision)
{
    TempDir dir;
    for (ScalarType t : {ScalarType::F32, ScalarType::I16}) {
        SCOPED_TRACE(scalarName(t));
        const fs::path raw = dir / "vol.raw", vdb = dir / "vol.vdb";
        writeFile(raw, volumeBytes(t, ByteOrder::Little));
        const auto r = raw2vdb({raw.string(), "-o", vdb.string(), "--dims", "20x17x13", "--type", scalarName(t), "--half"}, dir.path);
        ASSERT_EQ(r.code, 0) << r.err;
        auto grid = readVdb(vdb);
        ASSERT_TRUE(grid);
        // Stored as half: exactly the half rounding of each value, so within 2^-11 relative.
        expectVolume(*grid, kDims, [t](int x, int y, int z) { return float(openvdb::math::half(expected(x, y, z, t))); });
        auto acc = grid->getConstAccessor();
        for (int z = 0; z < NZ; ++z)
            for (int y = 0; y < NY; ++y)
                for (int x = 0; x < NX; ++x) {
                    const float want = expected(x, y, z, t);
                    ASSERT_LE(std::fabs(acc.getValue({x, y, z}) - want), std::fabs(want) * (1.0f / 2048.0f) + 1e-7f);
                }
    }
}

// ---------------------------------------------------------------------------------------------
// Acceptance 2: the same volume in every container gives identical grids and transforms.

TEST(Formats, EveryContainerGivesTheSameGridAndTransform)
{
    TempDir dir;
    const Geometry g;
    for (ScalarType t : {ScalarType::U16, ScalarType::F32}) {
        for (ByteOrder bo : {ByteOrder::Little, ByteOrder::Big}) {
            SCOPED_TRACE(std::string(scalarName(t)) + " " + byteOrderName(bo));
            const std::string data = volumeBytes(t, bo);
            writeFile(dir / "vol.raw", data);
            writeFile(dir / "attached_raw.nrrd", nrrdHeader(t, bo, "raw", g) + data);
            writeFile(dir / "attached_gzip.nrrd", nrrdHeader(t, bo, "gzip", g) + deflateBytes(data, true));
            writeFile(dir / "detached.nhdr", nrrdHeader(t, bo, "raw", g, "vol.raw"));
            writeFile(dir / "vol.raw.gz", deflateBytes(data, true));
            writeFile(dir / "detached_gz.nhdr", nrrdHeader(t, bo, "gz", g, "vol.raw.gz"));
            writeFile(dir / "detached.mhd", metaHeader(t, bo, false, g, "vol.raw"));
            writeFile(dir / "local_zlib.mha", metaHeader(t, bo, true, g, "LOCAL") + deflateBytes(data, false));
            writeFile(dir / "local_raw.mha", metaHeader(t, bo, false, g, "LOCAL") + data);
            const std::string nii = niftiBytes(t, bo, g, NiftiFields{}, data);
            writeFile(dir / "vol.nii", nii);
            writeFile(dir / "vol.nii.gz", deflateBytes(nii, true));

            RawConvertOptions rawOpt = rawOptions(t, bo);
            rawOpt.spacing = std::array<double, 3>{{0.5, 0.75, 1.25}};
            rawOpt.origin = g.origin;
            auto ref = convertToGrid((dir / "vol.raw").string(), rawOpt);
            const auto expect = [t](int x, int y, int z) { return expected(x, y, z, t); };
            expectVolume(*ref, kDims, expect);
            expectTransform(ref->transform(), g);

            for (const char* name : {"attached_raw.nrrd", "attached_gzip.nrrd", "detached.nhdr", "detached_gz.nhdr", "detached.mhd",
                                     "local_zlib.mha", "local_raw.mha", "vol.nii", "vol.nii.gz"}) {
                SCOPED_TRACE(name);
                RawConvertStats stats;
                auto grid = convertToGrid((dir / name).string(), RawConvertOptions{}, &stats);
                ASSERT_TRUE(grid);
                EXPECT_EQ(stats.info.dims, kDims);
                EXPECT_EQ(stats.info.type, t);
                EXPECT_EQ(stats.info.byteOrder, bo);
                expectVolume(*grid, kDims, expect);
                expectTransform(grid->transform(), g);
                EXPECT_TRUE(grid->transform() == ref->transform()) << grid->transform() << " vs " << ref->transform();
                EXPECT_EQ(grid->activeVoxelCount(), ref->activeVoxelCount());
                EXPECT_EQ(grid->tree().leafCount(), ref->tree().leafCount());
                EXPECT_EQ(grid->tree().activeTileCount(), ref->tree().activeTileCount());
            }
        }
    }
    // and through the program, headers read automatically (no options)
    for (const char* name : {"attached_gzip.nrrd", "detached.nhdr", "detached.mhd", "vol.nii.gz"}) {
        SCOPED_TRACE(name);
        const fs::path out = dir / (std::string(name) + ".vdb");
        const auto r = raw2vdb({(dir / name).string(), "-o", out.string()}, dir.path);
        ASSERT_EQ(r.code, 0) << r.err;
        auto grid = readVdb(out);
        ASSERT_TRUE(grid);
        expectVolume(*grid, kDims, [](int x, int y, int z) { return expected(x, y, z, ScalarType::F32); });
        expectTransform(grid->transform(), g);
    }
}

TEST(Formats, RotatedAxesAgreeAcrossHeaders)
{
    TempDir dir;
    // 30 degrees about z, non-uniform spacing, plus an origin.
    const double c = std::cos(M_PI / 6), s = std::sin(M_PI / 6);
    Geometry g;
    g.axes = {{{{0.5 * c, 0.5 * s, 0}}, {{-0.75 * s, 0.75 * c, 0}}, {{0, 0, 1.25}}}};
    g.origin = {{-7.5, 2.25, 100}};
    const ScalarType t = ScalarType::I16;
    const std::string data = volumeBytes(t, ByteOrder::Little);
    writeFile(dir / "vol.raw", data);
    writeFile(dir / "rot.nhdr", nrrdHeader(t, ByteOrder::Little, "raw", g, "vol.raw"));
    writeFile(dir / "rot.mhd", metaHeader(t, ByteOrder::Little, false, g, "vol.raw"));
    writeFile(dir / "sform.nii", niftiBytes(t, ByteOrder::Little, g, NiftiFields{}, data));
    NiftiFields q;
    q.sformCode = 0;
    q.qformCode = 1;
    q.quatern[2] = float(std::sin(M_PI / 12));  // d: rotation about z by 30 degrees
    for (int i = 0; i < 3; ++i) q.qoffset[i] = float(g.origin[i]);
    writeFile(dir / "qform.nii", niftiBytes(t, ByteOrder::Big, g, q, volumeBytes(t, ByteOrder::Big)));
    for (const char* name : {"rot.nhdr", "rot.mhd", "sform.nii", "qform.nii"}) {
        SCOPED_TRACE(name);
        auto grid = convertToGrid((dir / name).string(), RawConvertOptions{});
        ASSERT_TRUE(grid);
        expectVolume(*grid, kDims, [t](int x, int y, int z) { return expected(x, y, z, t); });
        // NIfTI stores the geometry as 32-bit floats
        expectTransform(grid->transform(), g, std::string(name).find(".nii") != std::string::npos ? 2e-5 : 1e-9);
    }
    // qfac = -1 flips the third axis
    q.qfac = -1;
    writeFile(dir / "qfac.nii", niftiBytes(t, ByteOrder::Little, g, q, data));
    auto grid = convertToGrid((dir / "qfac.nii").string(), RawConvertOptions{});
    Geometry flipped = g;
    flipped.axes[2] = {{0, 0, -1.25}};
    expectTransform(grid->transform(), flipped, 2e-5);
}

TEST(Formats, NiftiScalingAndPixdimFallback)
{
    TempDir dir;
    const ScalarType t = ScalarType::I16;
    const Geometry g;
    const std::string data = volumeBytes(t, ByteOrder::Little);
    NiftiFields nf;
    nf.slope = 2.0f;
    nf.inter = -3.0f;
    nf.sformCode = 0;  // neither sform nor qform: pixdim spacing, origin 0
    writeFile(dir / "scaled.nii", niftiBytes(t, ByteOrder::Little, g, nf, data));
    auto grid = convertToGrid((dir / "scaled.nii").string(), RawConvertOptions{});
    expectVolume(*grid, kDims, [t](int x, int y, int z) { return float(formula(x, y, z, t) * 2.0 - 3.0); });
    Geometry noOrigin = g;
    noOrigin.origin = {{0, 0, 0}};
    expectTransform(grid->transform(), noOrigin);
    // scl_slope 0 means no scaling
    nf.slope = 0;
    nf.inter = 5;
    writeFile(dir / "unscaled.nii", niftiBytes(t, ByteOrder::Little, g, nf, data));
    grid = convertToGrid((dir / "unscaled.nii").string(), RawConvertOptions{});
    expectVolume(*grid, kDims, [t](int x, int y, int z) { return expected(x, y, z, t); });
}

TEST(Formats, NrrdVariants)
{
    TempDir dir;
    const ScalarType t = ScalarType::U8;
    const std::string data = volumeBytes(t, ByteOrder::Little);
    // spacings instead of space directions, no origin; byte skip and line skip in a detached file
    const std::string header = "NRRD0001\ntype: unsigned char\ndimension: 3\nsizes: 20 17 13\nspacings: 0.5 0.75 1.25\n"
                               "encoding: raw\nline skip: 2\nbyte skip: 3\ndata file: ./skipped.dat\n";
    writeFile(dir / "vol.nhdr", header);
    writeFile(dir / "skipped.dat", "line one\nline two\nabc" + data);
    auto grid = convertToGrid((dir / "vol.nhdr").string(), RawConvertOptions{});
    expectVolume(*grid, kDims, [t](int x, int y, int z) { return expected(x, y, z, t); });
    Geometry g;
    g.origin = {{0, 0, 0}};
    expectTransform(grid->transform(), g);
    // byte skip -1: data at the end of the file
    writeFile(dir / "tail.nhdr", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 20 17 13\nbyte skip: -1\nencoding: raw\ndata file: tail.dat\n");
    writeFile(dir / "tail.dat", std::string(77, 'x') + data);
    grid = convertToGrid((dir / "tail.nhdr").string(), RawConvertOptions{});
    expectVolume(*grid, kDims, [t](int x, int y, int z) { return expected(x, y, z, t); });
    // two concatenated gzip members
    const std::size_t half = data.size() / 2;
    writeFile(dir / "members.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 20 17 13\nencoding: gzip\n\n" +
                                        deflateBytes(data.substr(0, half), true) + deflateBytes(data.substr(half), true));
    grid = convertToGrid((dir / "members.nrrd").string(), RawConvertOptions{});
    expectVolume(*grid, kDims, [t](int x, int y, int z) { return expected(x, y, z, t); });
}

// ---------------------------------------------------------------------------------------------
// Options

TEST(Options, ToleranceTurnsNearlyConstantLeavesIntoTiles)
{
    TempDir dir;
    const std::array<uint64_t, 3> dims{{32, 24, 16}};
    // 5 +- 0.01 everywhere except a varying corner and a background slab (x >= 24)
    const Formula f = [](int x, int y, int z) -> double {
        if (x >= 24) return 0.004 * ((x + y + z) % 3);  // within 0.02 of background
        if (x < 8 && y < 8) return (x * 7 + y * 3 + z) * 0.5;
        return 5.0 + 0.01 * ((x + 2 * y + 3 * z) % 3 - 1);
    };
    writeFile(dir / "vol.raw", volumeBytes(ScalarType::F32, ByteOrder::Little, dims, f));
    RawConvertOptions o;
    o.layout.dims = dims;
    o.layout.type = ScalarType::F32;
    RawConvertStats lossless, lossy;
    auto exact = convertToGrid((dir / "vol.raw").string(), o, &lossless);
    o.tolerance = 0.02;
    auto merged = convertToGrid((dir / "vol.raw").string(), o, &lossy);
    EXPECT_LT(lossy.leafCount, lossless.leafCount);
    EXPECT_GT(lossy.tileCount, lossless.tileCount);
    // the varying corner (x,y < 8) stays leaves; the 5 +- 0.01 region is all tiles
    EXPECT_NE(merged->tree().probeConstLeaf(openvdb::Coord(0, 0, 0)), nullptr);
    EXPECT_EQ(merged->tree().probeConstLeaf(openvdb::Coord(8, 8, 8)), nullptr);
    auto acc = merged->getConstAccessor();
    for (int z = 0; z < 16; ++z)
        for (int y = 0; y < 24; ++y)
            for (int x = 0; x < 32; ++x) {
                const float want = float(f(x, y, z));
                ASSERT_LE(std::fabs(acc.getValue({x, y, z}) - want), 0.02f + 1e-6f) << x << "," << y << "," << z;
                ASSERT_EQ(acc.isValueOn({x, y, z}), x < 24 && std::fabs(want) > 0.02f) << x << "," << y << "," << z;
            }
    // lossless: exact everywhere
    expectVolume(*exact, dims, [&](int x, int y, int z) { return float(f(x, y, z)); });
}

TEST(Options, ClampBackgroundNameAndLevelSetClass)
{
    TempDir dir;
    const ScalarType t = ScalarType::I16;
    writeFile(dir / "vol.raw", volumeBytes(t, ByteOrder::Little));
    RawConvertOptions o = rawOptions(t, ByteOrder::Little);
    o.clamp = std::array<double, 2>{{-1000, 5000}};
    auto grid = convertToGrid((dir / "vol.raw").string(), o);
    expectVolume(*grid, kDims, [t](int x, int y, int z) { return float(std::min(std::max(formula(x, y, z, t), -1000.0), 5000.0)); });

    // a non-zero background: voxels equal to it are inactive
    o = rawOptions(t, ByteOrder::Little);
    o.background = 42;
    grid = convertToGrid((dir / "vol.raw").string(), o);
    EXPECT_EQ(grid->background(), 42.0f);
    expectVolume(*grid, kDims, [t](int x, int y, int z) { return expected(x, y, z, t); }, 0.0f, 42.0f);

    // a signed distance field as a level set: narrow band active, inside -bg, outside +bg
    const std::array<uint64_t, 3> dims{{24, 24, 24}};
    const Formula sdf = [](int x, int y, int z) { return std::sqrt((x - 11.5) * (x - 11.5) + (y - 12.0) * (y - 12.0) + (z - 11.0) * (z - 11.0)) - 8.0; };
    writeFile(dir / "sdf.raw", volumeBytes(ScalarType::F32, ByteOrder::Little, dims, sdf));
    const auto r = raw2vdb({(dir / "sdf.raw").string(), "-o", (dir / "sdf.vdb").string(), "--dims", "24,24,24", "--type", "float",
                            "--class", "levelset", "--name", "ball", "--spacing", "0.5,0.5,0.5"},
                           dir.path);
    ASSERT_EQ(r.code, 0) << r.err;
    grid = readVdb(dir / "sdf.vdb");
    ASSERT_TRUE(grid);
    EXPECT_EQ(grid->getName(), "ball");
    EXPECT_EQ(grid->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_FLOAT_EQ(grid->background(), 1.5f);  // default: 3 x smallest spacing
    auto acc = grid->getConstAccessor();
    for (int z = 0; z < 24; ++z)
        for (int y = 0; y < 24; ++y)
            for (int x = 0; x < 24; ++x) {
                const float v = float(sdf(x, y, z));
                const float got = acc.getValue({x, y, z});
                if (v >= 1.5f) {
                    EXPECT_TRUE(!acc.isValueOn({x, y, z}) && got == 1.5f);
                } else if (v <= -1.5f) {
                    EXPECT_TRUE(!acc.isValueOn({x, y, z}) && got == -1.5f) << x << "," << y << "," << z << " " << got;
                } else {
                    EXPECT_TRUE(acc.isValueOn({x, y, z}) && got == v);
                }
            }
}

// ---------------------------------------------------------------------------------------------
// Acceptance 5: bad input -> one line naming the file and the problem, exit 1 (usage: 2), and
// nothing left in the output directory.

namespace {

/// Runs raw2vdb on `input` writing into a fresh directory, expects failure and a clean directory.
void expectFailure(const TempDir& dir, const std::string& input, const std::vector<std::string>& extra, int code,
                   const std::vector<std::string>& mustContain, const std::string& fileInMessage)
{
    const fs::path outDir = dir / "out";
    fs::create_directories(outDir);
    std::vector<std::string> args{input, "-o", (outDir / "result.vdb").string()};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = raw2vdb(args, dir.path);
    EXPECT_EQ(r.code, code) << r.err;
    ASSERT_FALSE(r.err.empty());
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(r.err.rfind("raw2vdb: ", 0), 0u) << r.err;
    if (!fileInMessage.empty()) {
        EXPECT_NE(r.err.find(fileInMessage + ": "), std::string::npos) << r.err;
    }
    for (const auto& word : mustContain) EXPECT_NE(r.err.find(word), std::string::npos) << "missing '" << word << "' in: " << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_TRUE(listDir(outDir).empty()) << "left behind: " << (listDir(outDir).empty() ? "" : listDir(outDir)[0]);
    fs::remove_all(outDir);
}

} // namespace

TEST(BadInput, RawSizeMismatchGivesBothNumbers)
{
    TempDir dir;
    const std::string data = volumeBytes(ScalarType::U16, ByteOrder::Little);  // 8840 bytes
    writeFile(dir / "long.raw", data + "xy");
    expectFailure(dir, (dir / "long.raw").string(), {"--dims", "20,17,13", "--type", "u16"}, 1, {"size mismatch", "8840", "8842"},
                  (dir / "long.raw").string());
    writeFile(dir / "short.raw", data.substr(0, 8000));
    expectFailure(dir, (dir / "short.raw").string(), {"--dims", "20,17,13", "--type", "u16"}, 1, {"truncated", "8840", "8000"},
                  (dir / "short.raw").string());
    // --skip counts
    writeFile(dir / "skip.raw", "HDR" + data);
    expectFailure(dir, (dir / "skip.raw").string(), {"--dims", "20,17,13", "--type", "u16", "--skip", "4"}, 1, {"truncated", "8840", "8839"},
                  (dir / "skip.raw").string());
}

TEST(BadInput, TruncatedFiles)
{
    TempDir dir;
    const Geometry g;
    const std::string data = volumeBytes(ScalarType::F32, ByteOrder::Little);
    writeFile(dir / "cut.nrrd", nrrdHeader(ScalarType::F32, ByteOrder::Little, "raw", g) + data.substr(0, data.size() - 100));
    expectFailure(dir, (dir / "cut.nrrd").string(), {}, 1, {"truncated", std::to_string(data.size())}, (dir / "cut.nrrd").string());
    writeFile(dir / "cut.nii", niftiBytes(ScalarType::F32, ByteOrder::Little, g, NiftiFields{}, data).substr(0, 5000));
    expectFailure(dir, (dir / "cut.nii").string(), {}, 1, {"truncated"}, (dir / "cut.nii").string());
    writeFile(dir / "tiny.nii", "short");
    expectFailure(dir, (dir / "tiny.nii").string(), {}, 1, {"not a NIfTI-1 file"}, (dir / "tiny.nii").string());
    // detached data file missing / short: the message names the data file
    writeFile(dir / "d.nhdr", nrrdHeader(ScalarType::F32, ByteOrder::Little, "raw", g, "d.raw"));
    writeFile(dir / "d.raw", data.substr(0, 10));
    expectFailure(dir, (dir / "d.nhdr").string(), {}, 1, {"truncated"}, (dir / "d.raw").string());
    // data said to fill the data file's end (NRRD byte skip -1, MetaImage HeaderSize = -1), but shorter
    writeFile(dir / "tail.nhdr", "NRRD0004\ntype: float\ndimension: 3\nsizes: 20 17 13\nbyte skip: -1\nencoding: raw\n"
                                 "data file: tail.raw\n");
    writeFile(dir / "tail.raw", data.substr(0, 1000));
    expectFailure(dir, (dir / "tail.nhdr").string(), {}, 1, {"truncated", std::to_string(data.size()), "1000"},
                  (dir / "tail.raw").string());
    writeFile(dir / "tail.mhd", "ObjectType = Image\nNDims = 3\nDimSize = 20 17 13\nElementType = MET_FLOAT\n"
                                "HeaderSize = -1\nElementDataFile = tail.raw\n");
    expectFailure(dir, (dir / "tail.mhd").string(), {}, 1, {"truncated", std::to_string(data.size()), "1000"},
                  (dir / "tail.raw").string());
    writeFile(dir / "m.mhd", metaHeader(ScalarType::F32, ByteOrder::Little, false, g, "missing.raw"));
    expectFailure(dir, (dir / "m.mhd").string(), {}, 1, {"cannot open"}, (dir / "missing.raw").string());
    expectFailure(dir, (dir / "nothere.nrrd").string(), {}, 1, {"cannot open"}, (dir / "nothere.nrrd").string());
}

TEST(BadInput, GzipStreamEndsEarly)
{
    TempDir dir;
    const Geometry g;
    const ScalarType t = ScalarType::U16;
    const std::string data = volumeBytes(t, ByteOrder::Little);
    const std::string gz = deflateBytes(data, true);
    // the compressed file is cut short
    writeFile(dir / "cut.nrrd", nrrdHeader(t, ByteOrder::Little, "gzip", g) + gz.substr(0, gz.size() / 2));
    expectFailure(dir, (dir / "cut.nrrd").string(), {}, 1, {"gzip stream ends early", std::to_string(data.size())}, (dir / "cut.nrrd").string());
    // a complete gzip stream holding too little data
    writeFile(dir / "few.nrrd", nrrdHeader(t, ByteOrder::Little, "gzip", g) + deflateBytes(data.substr(0, 1000), true));
    expectFailure(dir, (dir / "few.nrrd").string(), {}, 1, {"gzip stream ends early", "1000", std::to_string(data.size())},
                  (dir / "few.nrrd").string());
    // .nii.gz cut
    const std::string niigz = deflateBytes(niftiBytes(t, ByteOrder::Little, g, NiftiFields{}, data), true);
    writeFile(dir / "cut.nii.gz", niigz.substr(0, niigz.size() - 40));
    expectFailure(dir, (dir / "cut.nii.gz").string(), {}, 1, {"gzip stream ends early"}, (dir / "cut.nii.gz").string());
    // zlib (MetaImage) cut
    const std::string z = deflateBytes(data, false);
    writeFile(dir / "cut.mha", metaHeader(t, ByteOrder::Little, true, g, "LOCAL") + z.substr(0, z.size() / 3));
    expectFailure(dir, (dir / "cut.mha").string(), {}, 1, {"zlib stream ends early"}, (dir / "cut.mha").string());
    // garbage instead of compressed data
    std::string bad = gz;
    for (std::size_t i = 20; i < bad.size(); i += 7) bad[i] = char(bad[i] ^ 0x5a);
    writeFile(dir / "corrupt.nrrd", nrrdHeader(t, ByteOrder::Little, "gzip", g) + bad);
    expectFailure(dir, (dir / "corrupt.nrrd").string(), {}, 1, {"corrupt gzip data"}, (dir / "corrupt.nrrd").string());
}

TEST(BadInput, UnknownTypes)
{
    TempDir dir;
    writeFile(dir / "t.nrrd", "NRRD0004\ntype: long long\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n" + std::string(64, '\0'));
    expectFailure(dir, (dir / "t.nrrd").string(), {}, 1, {"unsupported type 'long long'"}, (dir / "t.nrrd").string());
    writeFile(dir / "t.mha", "NDims = 3\nDimSize = 2 2 2\nElementType = MET_LONG_LONG\nElementDataFile = LOCAL\n" + std::string(64, '\0'));
    expectFailure(dir, (dir / "t.mha").string(), {}, 1, {"unsupported type 'MET_LONG_LONG'"}, (dir / "t.mha").string());
    std::string nii = niftiBytes(ScalarType::U8, ByteOrder::Little, Geometry{}, NiftiFields{}, volumeBytes(ScalarType::U8, ByteOrder::Little));
    const int16_t rgb = 128;
    std::memcpy(&nii[70], &rgb, 2);
    writeFile(dir / "rgb.nii", nii);
    expectFailure(dir, (dir / "rgb.nii").string(), {}, 1, {"unsupported NIfTI datatype 128"}, (dir / "rgb.nii").string());
    // on the command line it is a usage error
    writeFile(dir / "v.raw", std::string(8, '\0'));
    expectFailure(dir, (dir / "v.raw").string(), {"--dims", "2,2,2", "--type", "u64"}, 2, {"--type", "unknown type 'u64'"}, "");
}

TEST(BadInput, DimsThatOverflow)
{
    TempDir dir;
    writeFile(dir / "big.nrrd", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2147483647 2147483647 2147483647\nencoding: raw\n\n" + std::string(64, '\0'));
    expectFailure(dir, (dir / "big.nrrd").string(), {}, 1, {"dims overflow", "2147483647x2147483647x2147483647"}, (dir / "big.nrrd").string());
    writeFile(dir / "huge.nhdr", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 99999999999999999999 1 1\nencoding: raw\ndata file: x.raw\n");
    expectFailure(dir, (dir / "huge.nhdr").string(), {}, 1, {"dims overflow"}, (dir / "huge.nhdr").string());
    writeFile(dir / "v.raw", std::string(8, '\0'));
    expectFailure(dir, (dir / "v.raw").string(), {"--dims", "4294967296,1,1", "--type", "u8"}, 1, {"dims overflow"}, (dir / "v.raw").string());
    writeFile(dir / "zero.mhd", "NDims = 3\nDimSize = 0 4 4\nElementType = MET_UCHAR\nElementDataFile = v.raw\n");
    expectFailure(dir, (dir / "zero.mhd").string(), {}, 1, {"invalid dims 0x4x4"}, (dir / "zero.mhd").string());
}

TEST(BadInput, UnwritableOutput)
{
    TempDir dir;
    writeFile(dir / "v.raw", volumeBytes(ScalarType::U8, ByteOrder::Little));
    fs::create_directories(dir / "out");
    writeFile(dir / "out" / "afile", "not a directory");
    const std::string target = (dir / "out" / "afile" / "result.vdb").string();
    const auto r = raw2vdb({(dir / "v.raw").string(), "-o", target, "--dims", "20,17,13", "--type", "u8"}, dir.path);
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(target + ": cannot write"), std::string::npos) << r.err;
    EXPECT_EQ(listDir(dir / "out"), std::vector<std::string>{"afile"});
    const auto r2 = raw2vdb({(dir / "v.raw").string(), "-o", (dir / "no" / "such" / "dir.vdb").string(), "--dims", "20,17,13", "--type", "u8"},
                            dir.path);
    EXPECT_EQ(r2.code, 1);
    EXPECT_NE(r2.err.find("cannot write"), std::string::npos) << r2.err;
    EXPECT_FALSE(fs::exists(dir / "no"));
}

TEST(BadInput, UsageErrors)
{
    TempDir dir;
    writeFile(dir / "v.raw", std::string(8, '\0'));
    expectFailure(dir, (dir / "v.raw").string(), {"--dims", "2,2"}, 2, {"--dims"}, "");
    expectFailure(dir, (dir / "v.raw").string(), {"--class", "cloud"}, 2, {"--class"}, "");
    expectFailure(dir, (dir / "v.raw").string(), {"--bogus"}, 2, {"bogus"}, "");
    // missing layout for a bare raw file is bad input (exit 1) naming the options
    expectFailure(dir, (dir / "v.raw").string(), {}, 1, {"--dims", "--type"}, (dir / "v.raw").string());
    const auto r = raw2vdb({"--help"}, dir.path);
    EXPECT_EQ(r.code, 0);
    EXPECT_NE(r.out.find("--tolerance"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Acceptance 4: raw2vdb output meshes exactly like a grid built in memory from the same values.

#ifdef VDB_ISOSIMP_EXE
TEST(Pipeline, Raw2vdbOutputMeshesLikeAnInMemoryGrid)
{
    TempDir dir;
    // CT-like: air 0, a soft-tissue ellipsoid ~1000 with a smooth ramp, a denser "bone" shell
    const std::array<uint64_t, 3> dims{{56, 48, 40}};
    const Formula ct = [](int x, int y, int z) -> double {
        const double u = (x - 27.5) / 24.0, v = (y - 23.5) / 20.0, w = (z - 19.5) / 17.0;
        const double r = std::sqrt(u * u + v * v + w * w);
        if (r > 1.0) return 0;
        double hu = r < 0.52 ? 1000 : 1000 + 40 * std::sin(x * 0.3) * std::cos(y * 0.2);  // constant core: tiles
        if (r > 0.55 && r < 0.7) hu = 1800 + 200 * (r - 0.55) / 0.15;
        return std::floor(hu);
    };
    writeFile(dir / "ct.raw", volumeBytes(ScalarType::U16, ByteOrder::Little, dims, ct));
    writeFile(dir / "ct.nhdr", "NRRD0004\ntype: ushort\ndimension: 3\nsizes: 56 48 40\nendian: little\nencoding: raw\n"
                               "space directions: (0.7,0,0) (0,0.7,0) (0,0,1.5)\nspace origin: (-20,-16,-30)\ndata file: ct.raw\n");
    auto r = raw2vdb({(dir / "ct.nhdr").string(), "-o", (dir / "converted.vdb").string()}, dir.path);
    ASSERT_EQ(r.code, 0) << r.err;

    auto converted = readVdb(dir / "converted.vdb");
    ASSERT_TRUE(converted);
    EXPECT_GT(converted->tree().activeTileCount(), 0u);  // the converter made tiles, the in-memory grid has none

    auto grid = openvdb::FloatGrid::create(0.0f);
    openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
    m[0][0] = 0.7;
    m[1][1] = 0.7;
    m[2][2] = 1.5;
    m[3][0] = -20;
    m[3][1] = -16;
    m[3][2] = -30;
    grid->setTransform(openvdb::math::Transform::createLinearTransform(m));
    grid->setName("density");
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    auto acc = grid->getAccessor();
    for (int z = 0; z < int(dims[2]); ++z)
        for (int y = 0; y < int(dims[1]); ++y)
            for (int x = 0; x < int(dims[0]); ++x)
                if (ct(x, y, z) != 0) acc.setValue({x, y, z}, float(ct(x, y, z)));
    openvdb::io::File((dir / "memory.vdb").string()).write({grid});

    EXPECT_EQ(grid->activeVoxelCount(), converted->activeVoxelCount());
    for (const char* iso : {"500", "1010", "1500"}) {
        SCOPED_TRACE(iso);
        r = runProgram(VDB_ISOSIMP_EXE, {(dir / "converted.vdb").string(), "--iso", iso, "-o", (dir / "a.ply").string()}, dir.path);
        ASSERT_EQ(r.code, 0) << r.err;
        r = runProgram(VDB_ISOSIMP_EXE, {(dir / "memory.vdb").string(), "--iso", iso, "-o", (dir / "b.ply").string()}, dir.path);
        ASSERT_EQ(r.code, 0) << r.err;
        const std::string a = readFile(dir / "a.ply"), b = readFile(dir / "b.ply");
        EXPECT_GT(a.size(), 1000u);
        EXPECT_TRUE(a == b) << "meshes differ (" << a.size() << " vs " << b.size() << " bytes)";
    }
}
#endif

// Tests of raw2vdb's image-stack inputs: DICOM series (written here with DCMTK) and TIFF stacks (written
// here with libtiff), converted by the library and by the program. Every slice's values come from a
// known formula, so each test compares voxel by voxel with what was written.
#include "program_runs.h"
#include "raw_converter.h"
#include "slice_source.h"

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>
#include <dcmtk/dcmdata/dcpixseq.h>
#include <dcmtk/dcmdata/dcpxitem.h>
#include <dcmtk/dcmdata/dcrleerg.h>
#include <dcmtk/dcmjpeg/djencode.h>
#include <dcmtk/oflog/oflog.h>
#include <gtest/gtest.h>
#include <openvdb/io/File.h>
#include <tiffio.h>
#include <zlib.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace vdb_isosimp;
using namespace vdb_isosimp::testing;

namespace {

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
constexpr bool kAddressSanitizer = __has_feature(address_sanitizer);
#else
constexpr bool kAddressSanitizer = false;
#endif

/// raw2vdb with at most `mib` MiB for any allocation: by its virtual memory (ulimit -v), or under
/// AddressSanitizer, whose shadow memory needs terabytes of address space, by its allocator's own limit
/// (allocations beyond it fail as they would).
RunResult raw2vdbWithMemoryLimit(std::vector<std::string> args, const fs::path& scratch, int mib)
{
    const std::string limit = kAddressSanitizer ? "ASAN_OPTIONS=\"${ASAN_OPTIONS:-}:max_allocation_size_mb=" + std::to_string(mib) +
                                                      ":allocator_may_return_null=1\" exec \"$0\" \"$@\""
                                                : "ulimit -v " + std::to_string(mib * 1024) + " && exec \"$0\" \"$@\"";
    args.insert(args.begin(), {"-c", limit, RAW2VDB_EXE});
    return runProgram("/bin/sh", args, scratch);
}

/// The program fails on `input` with `code`, one line on stderr naming `fileInMessage` and holding every
/// word of `mustContain`, nothing on stdout, and nothing left in the output folder. With
/// `addressSpaceMiB`, it runs with its memory limited to that (raw2vdbWithMemoryLimit).
void expectFailure(const TempDir& dir, const fs::path& input, const std::vector<std::string>& extra, int code,
                   const std::vector<std::string>& mustContain, const fs::path& fileInMessage, int addressSpaceMiB = 0)
{
    const fs::path outDir = dir / "out";
    fs::create_directories(outDir);
    std::vector<std::string> args{input.string(), "-o", (outDir / "result.vdb").string()};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = addressSpaceMiB > 0 ? raw2vdbWithMemoryLimit(args, dir.path, addressSpaceMiB) : raw2vdb(args, dir.path);
    std::printf("    %s", r.err.c_str());  // the message, for the log
    EXPECT_EQ(r.code, code) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(r.err.rfind("raw2vdb: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(fileInMessage.string() + ": "), std::string::npos) << "file not named: " << r.err;
    for (const auto& word : mustContain) EXPECT_NE(r.err.find(word), std::string::npos) << "missing '" << word << "' in: " << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_TRUE(fs::is_empty(outDir)) << "something was left in " << outDir;
    fs::remove_all(outDir);
}

/// Every voxel (x, y, z) of a dims-sized grid holds value(x, y, z) (exactly, or within tol) and nothing
/// is active outside.
void expectValues(const openvdb::FloatGrid& grid, const std::array<int, 3>& dims, const std::function<double(int, int, int)>& value,
                  double tol = 0)
{
    auto acc = grid.getConstAccessor();
    int bad = 0;
    uint64_t active = 0;
    for (int z = 0; z < dims[2]; ++z)
        for (int y = 0; y < dims[1]; ++y)
            for (int x = 0; x < dims[0]; ++x) {
                const float want = static_cast<float>(value(x, y, z));
                const float got = acc.getValue(openvdb::Coord(x, y, z));
                active += want != 0.0f;
                if (!(std::fabs(double(got) - double(want)) <= tol) && bad++ < 5)
                    ADD_FAILURE() << "voxel " << x << "," << y << "," << z << ": got " << got << ", expected " << want;
            }
    EXPECT_EQ(bad, 0);
    EXPECT_EQ(grid.activeVoxelCount(), active);
}

void expectNear3(const openvdb::Vec3d& got, const std::array<double, 3>& want, double tol, const std::string& what)
{
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(got[i], want[i], tol) << what << ": got " << got;
}

// ---------------------------------------------------------------------------------------------
// DICOM series written with DCMTK

void initDcmtkForTests()
{
    static std::once_flag once;
    std::call_once(once, [] {
        OFLog::getLogger("dcmtk").setLogLevel(OFLogger::OFF_LOG_LEVEL);
        DcmRLEEncoderRegistration::registerCodecs();
        DJEncoderRegistration::registerCodecs();
    });
}

using Vec3 = std::array<double, 3>;

struct SeriesSpec {
    int cols = 20, rows = 17, slices = 13;
    Vec3 row{{1, 0, 0}}, col{{0, 1, 0}};  // IOP
    Vec3 origin{{-120.5, 33.25, 10}};     // IPP of the first slice (lowest along the normal)
    double spacingRow = 0.7, spacingCol = 0.4;  // PixelSpacing: between rows (y), between columns (x)
    double step = 1.25;                         // between slices along the normal
    int bits = 16;
    int bitsStored = 0;  // 0: all bits; 12: values in the low 12 bits, junk above (overlay bits of old scanners)
    bool isSigned = true;
    double slope = 1, intercept = -1024;
    std::string series = "1.2.826.0.1.3680043.9.7777.1";
    E_TransferSyntax xfer = EXS_LittleEndianExplicit;
    bool withMeta = true;  // false: no preamble, no file-meta group (implicit VR little endian dataset)
};

Vec3 normalOf(const SeriesSpec& s)
{
    return {{s.row[1] * s.col[2] - s.row[2] * s.col[1], s.row[2] * s.col[0] - s.row[0] * s.col[2], s.row[0] * s.col[1] - s.row[1] * s.col[0]}};
}

Vec3 slicePosition(const SeriesSpec& s, int k)
{
    const Vec3 n = normalOf(s);
    return {{s.origin[0] + k * s.step * n[0], s.origin[1] + k * s.step * n[1], s.origin[2] + k * s.step * n[2]}};
}

/// The stored value of pixel (x, y) in slice k: spans negative and positive values, zero now and then.
int storedValue(int x, int y, int k, const SeriesSpec& s)
{
    const int p = (x * 7 + y * 13 + k * 29) % 251;
    if (s.bitsStored == 12) return s.isSigned ? (p - 100) * 13 : p * 16;
    if (s.bits == 8) return s.isSigned ? p / 2 - 60 : p;
    return s.isSigned ? (p - 100) * 37 : p * 211;
}

std::string ds(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.10g", v);
    return buf;
}

std::string ds3(const Vec3& v) { return ds(v[0]) + "\\" + ds(v[1]) + "\\" + ds(v[2]); }

/// Writes slice k of the series to `path` with position `ipp` (DCMTK, the spec's transfer syntax).
void writeDicomSlice(const fs::path& path, const SeriesSpec& s, int k, const Vec3& ipp)
{
    initDcmtkForTests();
    DcmFileFormat ff;
    DcmDataset* d = ff.getDataset();
    d->putAndInsertString(DCM_SOPClassUID, UID_CTImageStorage);
    d->putAndInsertString(DCM_SOPInstanceUID, (s.series + "." + std::to_string(k + 1)).c_str());
    d->putAndInsertString(DCM_Modality, "CT");
    d->putAndInsertString(DCM_SeriesInstanceUID, s.series.c_str());
    d->putAndInsertString(DCM_SeriesDescription, "test series");
    d->putAndInsertString(DCM_InstanceNumber, std::to_string(k + 1).c_str());
    d->putAndInsertString(DCM_ImagePositionPatient, ds3(ipp).c_str());
    d->putAndInsertString(DCM_ImageOrientationPatient, (ds3(s.row) + "\\" + ds3(s.col)).c_str());
    if (s.spacingRow > 0) d->putAndInsertString(DCM_PixelSpacing, (ds(s.spacingRow) + "\\" + ds(s.spacingCol)).c_str());
    d->putAndInsertString(DCM_SliceThickness, ds(s.step).c_str());
    d->putAndInsertString(DCM_RescaleSlope, ds(s.slope).c_str());
    d->putAndInsertString(DCM_RescaleIntercept, ds(s.intercept).c_str());
    d->putAndInsertUint16(DCM_Rows, static_cast<Uint16>(s.rows));
    d->putAndInsertUint16(DCM_Columns, static_cast<Uint16>(s.cols));
    d->putAndInsertUint16(DCM_SamplesPerPixel, 1);
    d->putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME2");
    d->putAndInsertUint16(DCM_BitsAllocated, static_cast<Uint16>(s.bits));
    const int stored = s.bitsStored ? s.bitsStored : s.bits;
    d->putAndInsertUint16(DCM_BitsStored, static_cast<Uint16>(stored));
    d->putAndInsertUint16(DCM_HighBit, static_cast<Uint16>(stored - 1));
    d->putAndInsertUint16(DCM_PixelRepresentation, s.isSigned ? 1 : 0);
    const std::size_t n = static_cast<std::size_t>(s.rows) * s.cols;
    if (s.bits == 8) {
        std::vector<Uint8> px(n);
        for (int y = 0; y < s.rows; ++y)
            for (int x = 0; x < s.cols; ++x) px[std::size_t(y) * s.cols + x] = static_cast<Uint8>(storedValue(x, y, k, s));
        d->putAndInsertUint8Array(DCM_PixelData, px.data(), static_cast<unsigned long>(n));
    } else {
        std::vector<Uint16> px(n);
        for (int y = 0; y < s.rows; ++y)
            for (int x = 0; x < s.cols; ++x) {
                Uint16 w = static_cast<Uint16>(storedValue(x, y, k, s));
                if (s.bitsStored == 12) w = static_cast<Uint16>((w & 0x0FFF) | (s.isSigned ? 0 : 0xA000));  // no sign bits / junk
                px[std::size_t(y) * s.cols + x] = w;
            }
        d->putAndInsertUint16Array(DCM_PixelData, px.data(), static_cast<unsigned long>(n));
    }
    if (DcmXfer(s.xfer).isEncapsulated()) {
        ASSERT_TRUE(d->chooseRepresentation(s.xfer, nullptr).good());
    }
    OFCondition c = s.withMeta ? ff.saveFile(path.c_str(), s.xfer)
                               : ff.saveFile(path.c_str(), EXS_LittleEndianImplicit, EET_ExplicitLength, EGL_recalcGL, EPD_noChange, 0, 0,
                                             EWM_dataset);
    ASSERT_TRUE(c.good()) << c.text();
}

/// Writes the whole series into `folder`, slice k under names[k] (default: "IM<k>").
void writeSeries(const fs::path& folder, const SeriesSpec& s, const std::vector<std::string>& names = {})
{
    fs::create_directories(folder);
    for (int k = 0; k < s.slices; ++k)
        writeDicomSlice(folder / (names.empty() ? "IM" + std::to_string(k) : names[std::size_t(k)]), s, k, slicePosition(s, k));
}

double huValue(const SeriesSpec& s, int x, int y, int k) { return storedValue(x, y, k, s) * s.slope + s.intercept; }

void expectSeriesGrid(const openvdb::FloatGrid& grid, const SeriesSpec& s)
{
    expectValues(grid, {{s.cols, s.rows, s.slices}}, [&](int x, int y, int z) { return huValue(s, x, y, z); });
    // Voxel (i, j, k) at IPP + i·Δcol·row + j·Δrow·col + k·step·normal (LPS, as written).
    const Vec3 n = normalOf(s);
    for (const auto& ijk : {openvdb::Vec3d(0, 0, 0), openvdb::Vec3d(3, 5, 7), openvdb::Vec3d(s.cols - 1, s.rows - 1, s.slices - 1)}) {
        Vec3 want;
        for (int a = 0; a < 3; ++a)
            want[a] = s.origin[a] + ijk[0] * s.spacingCol * s.row[a] + ijk[1] * s.spacingRow * s.col[a] + ijk[2] * s.step * n[a];
        expectNear3(grid.transform().indexToWorld(ijk), want, 1e-6, "world position of voxel " + std::to_string(ijk[0]) + "," +
                                                                        std::to_string(ijk[1]) + "," + std::to_string(ijk[2]));
    }
}

// ---------------------------------------------------------------------------------------------
// TIFF stacks written with libtiff

struct TiffSpec {
    int width = 21, height = 18, pages = 11;
    int bits = 16;
    int sampleFormat = SAMPLEFORMAT_UINT;
    int samples = 1;
    std::string description;  // ImageJ's, or empty
    float xres = 0, yres = 0;  // 0: no resolution tags
    int resUnit = RESUNIT_NONE;
    bool tiled = false;
    int compression = COMPRESSION_NONE;
};

double tiffValue(int x, int y, int z, const TiffSpec& t)
{
    const int p = (x * 5 + y * 11 + z * 17) % 199;
    if (t.sampleFormat == SAMPLEFORMAT_IEEEFP) return (p - 99) * 0.25;
    if (t.bits == 8) return t.sampleFormat == SAMPLEFORMAT_INT ? p / 2 - 50 : p;
    if (t.bits == 16) return t.sampleFormat == SAMPLEFORMAT_INT ? (p - 99) * 301 : p * 301;
    return t.sampleFormat == SAMPLEFORMAT_INT ? (p - 99) * 70001 : p * 70001;
}

template <typename T>
void fillRow(std::vector<unsigned char>& row, int y, int z, const TiffSpec& t)
{
    for (int x = 0; x < t.width; ++x)
        for (int c = 0; c < t.samples; ++c) {
            const T v = static_cast<T>(tiffValue(x, y, z, t));
            std::memcpy(row.data() + (std::size_t(x) * t.samples + c) * sizeof(T), &v, sizeof(T));
        }
}

std::vector<unsigned char> pageRow(int y, int z, const TiffSpec& t)
{
    std::vector<unsigned char> row(std::size_t(t.width) * t.samples * (t.bits / 8));
    const bool f = t.sampleFormat == SAMPLEFORMAT_IEEEFP, s = t.sampleFormat == SAMPLEFORMAT_INT;
    switch (t.bits) {
    case 8: s ? fillRow<int8_t>(row, y, z, t) : fillRow<uint8_t>(row, y, z, t); break;
    case 16: s ? fillRow<int16_t>(row, y, z, t) : fillRow<uint16_t>(row, y, z, t); break;
    case 32: f ? fillRow<float>(row, y, z, t) : s ? fillRow<int32_t>(row, y, z, t) : fillRow<uint32_t>(row, y, z, t); break;
    case 64: fillRow<double>(row, y, z, t); break;
    }
    return row;
}

/// Writes page z of the stack as the current directory of `tif`.
void writePage(TIFF* tif, const TiffSpec& t, int z)
{
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, uint32_t(t.width));
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, uint32_t(t.height));
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, uint16_t(t.bits));
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, uint16_t(t.samples));
    TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, uint16_t(t.sampleFormat));
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, t.samples == 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK);
    TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    TIFFSetField(tif, TIFFTAG_COMPRESSION, uint16_t(t.compression));
    if (t.compression == COMPRESSION_LZW || t.compression == COMPRESSION_ADOBE_DEFLATE)
        TIFFSetField(tif, TIFFTAG_PREDICTOR, t.bits == 8 || t.bits == 16 ? PREDICTOR_HORIZONTAL : PREDICTOR_NONE);
    if (!t.description.empty() && z == 0) TIFFSetField(tif, TIFFTAG_IMAGEDESCRIPTION, t.description.c_str());
    if (t.xres > 0) {
        TIFFSetField(tif, TIFFTAG_XRESOLUTION, t.xres);
        TIFFSetField(tif, TIFFTAG_YRESOLUTION, t.yres);
        TIFFSetField(tif, TIFFTAG_RESOLUTIONUNIT, uint16_t(t.resUnit));
    }
    if (t.tiled) {
        TIFFSetField(tif, TIFFTAG_TILEWIDTH, uint32_t(16));
        TIFFSetField(tif, TIFFTAG_TILELENGTH, uint32_t(16));
        const std::size_t bytes = t.bits / 8 * t.samples;
        std::vector<unsigned char> tile(16 * 16 * bytes);
        for (int y0 = 0; y0 < t.height; y0 += 16)
            for (int x0 = 0; x0 < t.width; x0 += 16) {
                std::fill(tile.begin(), tile.end(), 0);
                for (int r = 0; r < 16 && y0 + r < t.height; ++r) {
                    const auto row = pageRow(y0 + r, z, t);
                    const int cols = std::min(16, t.width - x0);
                    std::memcpy(tile.data() + std::size_t(r) * 16 * bytes, row.data() + std::size_t(x0) * bytes, cols * bytes);
                }
                ASSERT_GE(TIFFWriteTile(tif, tile.data(), uint32_t(x0), uint32_t(y0), 0, 0), 0);
            }
    } else {
        TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, uint32_t(5));
        for (int y = 0; y < t.height; ++y) {
            auto row = pageRow(y, z, t);
            ASSERT_EQ(TIFFWriteScanline(tif, row.data(), uint32_t(y), 0), 1);
        }
    }
    ASSERT_EQ(TIFFWriteDirectory(tif), 1);
}

/// A multi-page TIFF of t.pages pages; `perPage` may change the spec of one page (mixed sizes, types).
void writeTiffStack(const fs::path& path, const TiffSpec& t, const std::function<void(int, TiffSpec&)>& perPage = {})
{
    TIFF* tif = TIFFOpen(path.c_str(), "w");
    ASSERT_NE(tif, nullptr);
    for (int z = 0; z < t.pages; ++z) {
        TiffSpec p = t;
        if (perPage) perPage(z, p);
        writePage(tif, p, z);
    }
    TIFFClose(tif);
}

void writeTiffPage(const fs::path& path, const TiffSpec& t, int z)
{
    TIFF* tif = TIFFOpen(path.c_str(), "w");
    ASSERT_NE(tif, nullptr);
    writePage(tif, t, z);
    TIFFClose(tif);
}

void expectTiffGrid(const openvdb::FloatGrid& grid, const TiffSpec& t)
{
    expectValues(grid, {{t.width, t.height, t.pages}}, [&](int x, int y, int z) { return tiffValue(x, y, z, t); });
}

openvdb::FloatGrid::Ptr convert(const fs::path& input, RawConvertOptions options = {}, RawConvertStats* stats = nullptr)
{
    return convertToGrid(input.string(), options, stats);
}

} // namespace

// =============================================================================================
// DICOM

TEST(Dicom, ValuesInHounsfieldUnitsVoxelSizeAndOrigin)
{
    TempDir dir;
    SeriesSpec s;
    writeSeries(dir / "ct", s);
    RawConvertStats stats;
    auto grid = convert(dir / "ct", {}, &stats);
    expectSeriesGrid(*grid, s);
    const auto vs = grid->voxelSize();
    expectNear3(vs, {{0.4, 0.7, 1.25}}, 1e-9, "voxel size (PixelSpacing column, row; slice step)");
    EXPECT_EQ(stats.info.format, VolumeFormat::Dicom);
    EXPECT_EQ(stats.info.type, ScalarType::I16);
    EXPECT_NE(stats.source.find("13 files"), std::string::npos) << stats.source;
    // Rescaling matters: stored 0 is -1024 HU.
    EXPECT_EQ(grid->tree().getValue(openvdb::Coord(0, 0, 0)), float(storedValue(0, 0, 0, s) - 1024));
}

TEST(Dicom, EveryStoredTypeAndRescale)
{
    for (int bits : {8, 16})
        for (bool isSigned : {false, true}) {
            TempDir dir;
            SeriesSpec s;
            s.bits = bits;
            s.isSigned = isSigned;
            s.slope = 2.5;
            s.intercept = -7;
            s.slices = 9;
            writeSeries(dir / "s", s);
            auto grid = convert(dir / "s");
            SCOPED_TRACE("bits " + std::to_string(bits) + (isSigned ? " signed" : " unsigned"));
            expectSeriesGrid(*grid, s);
        }
}

TEST(Dicom, TwelveBitsStoredAreMaskedAndSignExtended)
{
    for (bool isSigned : {false, true}) {
        TempDir dir;
        SeriesSpec s;
        s.bitsStored = 12;
        s.isSigned = isSigned;
        s.slices = 9;
        writeSeries(dir / "s", s);
        SCOPED_TRACE(isSigned ? "signed 12 of 16 bits, upper bits clear" : "unsigned 12 of 16 bits, junk in the upper bits");
        expectSeriesGrid(*convert(dir / "s"), s);
    }
}

TEST(Dicom, SlicesShuffledOnDiskAreSortedByPosition)
{
    TempDir dir;
    SeriesSpec s;
    // Names that sort against the positions, and positions written in a shuffled order.
    std::vector<std::string> names;
    std::vector<int> order(std::size_t(s.slices));
    for (int k = 0; k < s.slices; ++k) order[std::size_t(k)] = k;
    std::shuffle(order.begin(), order.end(), std::mt19937(7));
    for (int k = 0; k < s.slices; ++k) names.push_back("slice_" + std::to_string(order[std::size_t(k)]) + ".dcm");
    writeSeries(dir / "ct", s, names);
    ASSERT_NE(order.front(), 0);
    auto grid = convert(dir / "ct");
    expectSeriesGrid(*grid, s);
}

TEST(Dicom, PositionsDescendingAlongTheNormalStillGiveIncreasingK)
{
    // Feet-first: the normal of IOP points down the table while slices were written head to feet.
    TempDir dir;
    SeriesSpec s;
    s.row = {{-1, 0, 0}};  // normal (0, 0, -1)
    s.origin = {{10, 20, 300}};
    writeSeries(dir / "ct", s);
    auto grid = convert(dir / "ct");
    expectSeriesGrid(*grid, s);
    EXPECT_GT(grid->transform().indexToWorld(openvdb::Vec3d(0, 0, 0))[2], grid->transform().indexToWorld(openvdb::Vec3d(0, 0, 1))[2]);
}

TEST(Dicom, FilesWithoutPreambleAndMetaGroupAreRead)
{
    TempDir dir;
    SeriesSpec s;
    s.withMeta = false;
    writeSeries(dir / "old", s);
    // No "DICM" at byte 128: a bare implicit-VR dataset starting with group 0008.
    const std::string bytes = readFile(dir / "old" / "IM0");
    ASSERT_GT(bytes.size(), 132u);
    EXPECT_NE(bytes.substr(128, 4), "DICM");
    EXPECT_EQ(bytes[0], 0x08);
    EXPECT_EQ(bytes[1], 0x00);
    auto grid = convert(dir / "old");
    expectSeriesGrid(*grid, s);

    // Mixed in one folder: half with, half without.
    SeriesSpec m;
    writeSeries(dir / "mixed", m);
    m.withMeta = false;
    for (int k = 0; k < m.slices; k += 2) writeDicomSlice(dir / "mixed" / ("IM" + std::to_string(k)), m, k, slicePosition(m, k));
    expectSeriesGrid(*convert(dir / "mixed"), m);
}

TEST(Dicom, ObliqueOrientationMapsToTheRightWorldPositions)
{
    TempDir dir;
    SeriesSpec s;
    // IOP rotated 30 degrees about z, then 20 degrees about the new x axis.
    const double a = 30 * M_PI / 180, b = 20 * M_PI / 180;
    s.row = {{std::cos(a), std::sin(a), 0}};
    s.col = {{-std::sin(a) * std::cos(b), std::cos(a) * std::cos(b), std::sin(b)}};
    writeSeries(dir / "oblique", s);
    auto grid = convert(dir / "oblique");
    expectSeriesGrid(*grid, s);
    // A point check with numbers worked out by hand: voxel (3, 5, 7).
    //   row = (0.8660254, 0.5, 0), col = (-0.4698463, 0.8137977, 0.3420201),
    //   normal = row x col = (0.1710101, -0.2961981, 0.9396926)
    //   origin + 3*0.4*row + 5*0.7*col + 7*1.25*normal
    const openvdb::Vec3d w = grid->transform().indexToWorld(openvdb::Vec3d(3, 5, 7));
    expectNear3(w, {{-120.5 + 1.0392305 - 1.6444621 + 1.4963384, 33.25 + 0.6 + 2.8482920 - 2.5917334, 10 + 0 + 1.1970704 + 8.2223103}},
                1e-6, "voxel 3,5,7");
    // And the value there is slice 7's pixel (3, 5).
    EXPECT_EQ(grid->tree().getValue(openvdb::Coord(3, 5, 7)), float(huValue(s, 3, 5, 7)));
}

TEST(Dicom, CompressedTransferSyntaxesAreDecoded)
{
    for (E_TransferSyntax xfer : {EXS_RLELossless, EXS_JPEGProcess14SV1, EXS_DeflatedLittleEndianExplicit}) {
        TempDir dir;
        SeriesSpec s;
        s.xfer = xfer;
        s.isSigned = false;  // DCMTK's lossless JPEG encoder codes unsigned samples
        s.slices = 9;
        writeSeries(dir / "c", s);
        RawConvertStats stats;
        auto grid = convert(dir / "c", {}, &stats);
        SCOPED_TRACE(DcmXfer(xfer).getXferName());
        EXPECT_NE(stats.source.find(DcmXfer(xfer).getXferName()), std::string::npos) << stats.source;
        expectSeriesGrid(*grid, s);
    }
}

TEST(Dicom, PerSliceRescaleIsAppliedSliceBySlice)
{
    TempDir dir;
    SeriesSpec s;
    fs::create_directories(dir / "pet");
    auto slope = [](int k) { return 0.5 + 0.25 * k; };
    for (int k = 0; k < s.slices; ++k) {
        SeriesSpec sk = s;
        sk.slope = slope(k);
        sk.intercept = -3.0 * k;
        writeDicomSlice(dir / "pet" / ("IM" + std::to_string(k)), sk, k, slicePosition(s, k));
    }
    RawConvertStats stats;
    auto grid = convert(dir / "pet", {}, &stats);
    EXPECT_EQ(stats.info.type, ScalarType::F32);
    expectValues(*grid, {{s.cols, s.rows, s.slices}}, [&](int x, int y, int k) { return storedValue(x, y, k, s) * slope(k) - 3.0 * k; });
}

TEST(Dicom, SeveralSeriesNeedSeriesAndItPicksOne)
{
    TempDir dir;
    SeriesSpec a, b;
    b.series = "1.2.826.0.1.3680043.9.7777.2";
    b.intercept = 0;
    writeSeries(dir / "study", a);
    std::vector<std::string> names;
    for (int k = 0; k < b.slices; ++k) names.push_back("B" + std::to_string(k));
    writeSeries(dir / "study", b, names);
    expectFailure(dir, dir / "study", {}, 1, {"2 series", a.series, b.series, "--series"}, dir / "study");
    expectFailure(dir, dir / "study", {"--series", "9.9.9"}, 1, {"no image of series 9.9.9"}, dir / "study");

    // --series through the program: the grid is series b's.
    const auto r = raw2vdb({(dir / "study").string(), "-o", (dir / "b.vdb").string(), "--series", b.series}, dir.path);
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("DICOM series " + b.series), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("voxel 0.4x0.7x1.25"), std::string::npos) << r.out;
    expectSeriesGrid(*readVdb(dir / "b.vdb"), b);
}

TEST(Dicom, NonImageFilesBesideTheSeriesAreSkipped)
{
    TempDir dir;
    SeriesSpec s;
    writeSeries(dir / "ct", s);
    writeFile(dir / "ct" / "README.txt", "exported by the scanner\n");
    writeFile(dir / "ct" / ".hidden", "x");
    // A DICOM object that is no image (no Rows/Columns), like a DICOMDIR or a report.
    DcmFileFormat ff;
    ff.getDataset()->putAndInsertString(DCM_SOPClassUID, UID_BasicTextSRStorage);
    ff.getDataset()->putAndInsertString(DCM_SeriesInstanceUID, "1.2.3.999");
    ASSERT_TRUE(ff.saveFile((dir / "ct" / "SR0001").c_str(), EXS_LittleEndianExplicit).good());
    expectSeriesGrid(*convert(dir / "ct"), s);
}

// =============================================================================================
// TIFF

TEST(Tiff, MultiPageEveryTypeValuesAsWritten)
{
    const std::pair<int, int> types[] = {{8, SAMPLEFORMAT_UINT}, {8, SAMPLEFORMAT_INT}, {16, SAMPLEFORMAT_UINT}, {16, SAMPLEFORMAT_INT},
                                         {32, SAMPLEFORMAT_UINT}, {32, SAMPLEFORMAT_INT}, {32, SAMPLEFORMAT_IEEEFP}, {64, SAMPLEFORMAT_IEEEFP}};
    for (const auto& [bits, format] : types) {
        TempDir dir;
        TiffSpec t;
        t.bits = bits;
        t.sampleFormat = format;
        writeTiffStack(dir / "stack.tif", t);
        RawConvertStats stats;
        auto grid = convert(dir / "stack.tif", {}, &stats);
        SCOPED_TRACE(std::to_string(bits) + "-bit format " + std::to_string(format));
        EXPECT_EQ(stats.info.format, VolumeFormat::Tiff);
        EXPECT_EQ(stats.info.dims[2], uint64_t(t.pages));
        expectTiffGrid(*grid, t);
        expectNear3(grid->voxelSize(), {{1, 1, 1}}, 0, "no spacing in the file");
    }
}

TEST(Tiff, ImageJSpacingGivesVoxelSizeZ)
{
    TempDir dir;
    TiffSpec t;
    t.description = "ImageJ=1.54f\nimages=11\nslices=11\nunit=micron\nspacing=4.0\nloop=false\n";
    t.xres = 1 / 0.325f;  // ImageJ writes pixels per unit
    t.yres = 1 / 0.5f;
    writeTiffStack(dir / "lightsheet.tif", t);
    auto grid = convert(dir / "lightsheet.tif");
    expectTiffGrid(*grid, t);
    expectNear3(grid->voxelSize(), {{0.325, 0.5, 4.0}}, 1e-6, "ImageJ voxel size");

    // Through the program, with ImageJ's escaped µ and a unit in nanometres.
    t.description = "ImageJ=1.54f\nimages=11\nslices=11\nunit=nm\nspacing=250\n";
    t.xres = 1 / 100.0f;
    t.yres = 1 / 100.0f;
    writeTiffStack(dir / "nm.tif", t);
    const auto r = raw2vdb({(dir / "nm.tif").string(), "-o", (dir / "nm.vdb").string()}, dir.path);
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("TIFF stack, 11 pages"), std::string::npos) << r.out;
    expectNear3(readVdb(dir / "nm.vdb")->voxelSize(), {{0.1, 0.1, 0.25}}, 1e-6, "nm in micrometres");
}

TEST(Tiff, ResolutionInCentimetresWithoutImageJ)
{
    TempDir dir;
    TiffSpec t;
    t.xres = 20000;  // pixels per cm: 0.5 µm
    t.yres = 40000;
    t.resUnit = RESUNIT_CENTIMETER;
    writeTiffStack(dir / "s.tif", t);
    expectNear3(convert(dir / "s.tif")->voxelSize(), {{0.5, 0.25, 1}}, 1e-6, "pixels per cm");
    t.resUnit = RESUNIT_INCH;  // print resolution: ignored
    t.xres = t.yres = 72;
    writeTiffStack(dir / "print.tif", t);
    expectNear3(convert(dir / "print.tif")->voxelSize(), {{1, 1, 1}}, 0, "inch resolution ignored");
}

TEST(Tiff, TiledAndCompressedPages)
{
    for (int compression : {COMPRESSION_LZW, COMPRESSION_ADOBE_DEFLATE, COMPRESSION_PACKBITS})
        for (bool tiled : {false, true}) {
            TempDir dir;
            TiffSpec t;
            t.width = 37;  // partial tiles on both axes
            t.height = 20;
            t.compression = compression;
            t.tiled = tiled;
            writeTiffStack(dir / "c.tif", t);
            SCOPED_TRACE("compression " + std::to_string(compression) + (tiled ? " tiled" : " strips"));
            expectTiffGrid(*convert(dir / "c.tif"), t);
        }
}

TEST(Tiff, FolderOfSlicesInNaturalOrderWithSpacingOption)
{
    TempDir dir;
    TiffSpec t;
    t.pages = 12;
    fs::create_directories(dir / "slices");
    // slice_2 must come before slice_10 (plain string order would not).
    for (int z = 0; z < t.pages; ++z) writeTiffPage(dir / "slices" / ("slice_" + std::to_string(z + 1) + ".tif"), t, z);
    writeFile(dir / "slices" / "notes.txt", "acquired on tuesday\n");
    const auto r = raw2vdb({(dir / "slices").string(), "-o", (dir / "s.vdb").string(), "--spacing", "0.5,0.5,2"}, dir.path);
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("TIFF folder, 12 files"), std::string::npos) << r.out;
    auto grid = readVdb(dir / "s.vdb");
    expectTiffGrid(*grid, t);
    expectNear3(grid->voxelSize(), {{0.5, 0.5, 2}}, 1e-9, "--spacing");
}

TEST(NaturalOrder, DigitRunsCompareByValue)
{
    EXPECT_TRUE(naturalLess("slice_2.tif", "slice_10.tif"));
    EXPECT_FALSE(naturalLess("slice_10.tif", "slice_2.tif"));
    EXPECT_TRUE(naturalLess("a9b", "a10a"));
    EXPECT_TRUE(naturalLess("img001", "img002"));
    EXPECT_TRUE(naturalLess("img1", "img01"));  // equal values: fewer zeros first, a strict order
    EXPECT_FALSE(naturalLess("img01", "img1"));
    EXPECT_TRUE(naturalLess("a", "ab"));
    EXPECT_FALSE(naturalLess("x7", "x7"));
}

// =============================================================================================
// Bad input: one line naming the file and the problem, exit 1, nothing left behind.

TEST(StackBadInput, DicomTruncatedFile)
{
    TempDir dir;
    SeriesSpec s;
    writeSeries(dir / "ct", s);
    const std::string bytes = readFile(dir / "ct" / "IM5");
    writeFile(dir / "ct" / "IM5", bytes.substr(0, bytes.size() - 300));
    expectFailure(dir, dir / "ct", {}, 1, {"truncated"}, dir / "ct" / "IM5");
    // Cut inside the header.
    writeFile(dir / "ct" / "IM5", bytes.substr(0, 200));
    expectFailure(dir, dir / "ct", {}, 1, {"damaged or truncated DICOM file"}, dir / "ct" / "IM5");
    // A compressed slice cut short is found when it is decoded.
    SeriesSpec r;
    r.xfer = EXS_RLELossless;
    writeSeries(dir / "rle", r);
    const std::string rle = readFile(dir / "rle" / "IM3");
    writeFile(dir / "rle" / "IM3", rle.substr(0, rle.size() - 100));
    expectFailure(dir, dir / "rle", {}, 1, {"DICOM"}, dir / "rle" / "IM3");
}

TEST(StackBadInput, DicomMixedSizesAndTypes)
{
    TempDir dir;
    SeriesSpec s;
    writeSeries(dir / "sizes", s);
    SeriesSpec other = s;
    other.cols = 24;
    writeDicomSlice(dir / "sizes" / "IM4", other, 4, slicePosition(s, 4));
    expectFailure(dir, dir / "sizes", {}, 1, {"mixed sizes", "24x17", "20x17"}, dir / "sizes" / "IM4");

    writeSeries(dir / "types", s);
    other = s;
    other.bits = 8;
    writeDicomSlice(dir / "types" / "IM7", other, 7, slicePosition(s, 7));
    expectFailure(dir, dir / "types", {}, 1, {"mixed types", "8 of 8 bits", "16 of 16 bits"}, dir / "types" / "IM7");
}

TEST(StackBadInput, DicomUnevenAndDuplicatePositions)
{
    TempDir dir;
    SeriesSpec s;
    writeSeries(dir / "gap", s);
    fs::remove(dir / "gap" / "IM6");  // a missing slice
    expectFailure(dir, dir / "gap", {}, 1, {"uneven slice spacing", "2.5 mm", "IM5", "IM7"}, dir / "gap");

    writeSeries(dir / "dup", s);
    writeDicomSlice(dir / "dup" / "IM6b", s, 6, slicePosition(s, 6));
    expectFailure(dir, dir / "dup", {}, 1, {"same position"}, dir / "dup");
}

TEST(StackBadInput, DicomWithoutPixelSpacingNeedsTheOption)
{
    TempDir dir;
    SeriesSpec s;
    s.spacingRow = 0;  // no PixelSpacing (0028,0030)
    writeSeries(dir / "nops", s);
    expectFailure(dir, dir / "nops", {}, 1, {"PixelSpacing", "--spacing"}, dir / "nops");
    const auto r = raw2vdb({(dir / "nops").string(), "-o", (dir / "o.vdb").string(), "--spacing", "0.5,0.5,2", "-q"}, dir.path);
    ASSERT_EQ(r.code, 0) << r.err;
    expectNear3(readVdb(dir / "o.vdb")->voxelSize(), {{0.5, 0.5, 2}}, 1e-9, "--spacing");
}

TEST(StackBadInput, DicomUndecodableTransferSyntaxIsNamed)
{
    TempDir dir;
    SeriesSpec s;
    s.slices = 3;
    writeSeries(dir / "j2k", s);
    // Slice 1 as JPEG 2000 (which DCMTK's free toolkit cannot decode): an encapsulated fragment.
    initDcmtkForTests();
    DcmFileFormat ff;
    ASSERT_TRUE(ff.loadFile((dir / "j2k" / "IM1").c_str()).good());
    DcmDataset* d = ff.getDataset();
    d->findAndDeleteElement(DCM_PixelData);
    auto* pixels = new DcmPixelData(DCM_PixelData);
    auto* seq = new DcmPixelSequence(DCM_PixelSequenceTag);
    seq->insert(new DcmPixelItem(DCM_PixelItemTag));  // empty offset table
    auto* fragment = new DcmPixelItem(DCM_PixelItemTag);
    const Uint8 junk[8] = {0xff, 0x4f, 0xff, 0x51, 0, 0, 0, 0};
    fragment->putUint8Array(junk, 8);
    seq->insert(fragment);
    pixels->putOriginalRepresentation(EXS_JPEG2000LosslessOnly, nullptr, seq);
    d->insert(pixels, true);
    ASSERT_TRUE(ff.saveFile((dir / "j2k" / "IM1").c_str(), EXS_JPEG2000LosslessOnly).good());
    expectFailure(dir, dir / "j2k", {}, 1, {"JPEG 2000", "1.2.840.10008.1.2.4.90", "cannot decode"}, dir / "j2k" / "IM1");
}

/// Raw deflate (RFC 1951), as the Deflated Explicit VR Little Endian transfer syntax stores a dataset.
std::string rawDeflate(const std::string& in, bool inflate)
{
    z_stream z{};
    EXPECT_EQ(inflate ? inflateInit2(&z, -MAX_WBITS) : deflateInit2(&z, 6, Z_DEFLATED, -MAX_WBITS, 8, Z_DEFAULT_STRATEGY), Z_OK);
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
    z.avail_in = static_cast<uInt>(in.size());
    std::string out;
    char buf[65536];
    int rc = Z_OK;
    while (rc == Z_OK) {
        z.next_out = reinterpret_cast<Bytef*>(buf);
        z.avail_out = sizeof buf;
        rc = inflate ? ::inflate(&z, Z_NO_FLUSH) : ::deflate(&z, Z_FINISH);
        out.append(buf, sizeof buf - z.avail_out);
    }
    EXPECT_EQ(rc, Z_STREAM_END);
    if (inflate) inflateEnd(&z);
    else deflateEnd(&z);
    return out;
}

TEST(StackBadInput, DicomDeflatedLengthBeyondTheData)
{
    // A deflated slice holding an element that claims 4 GiB. Read in order from the compressed
    // stream, DCMTK would allocate the declared length before finding the stream's end; the reader
    // must find the damage without that allocation, so the program runs with 1 GiB at most.
    TempDir dir;
    SeriesSpec s;
    s.xfer = EXS_DeflatedLittleEndianExplicit;
    s.slices = 4;
    writeSeries(dir / "ct", s);
    const std::string file = readFile(dir / "ct" / "IM2");
    uint32_t metaLength = 0;  // (0002,0000) after the preamble: the meta group's length
    std::memcpy(&metaLength, file.data() + 140, 4);
    const std::size_t datasetAt = 144 + metaLength;
    const std::string dataset = rawDeflate(file.substr(datasetAt), true);
    const std::string pixelTag("\xe0\x7f\x10\x00", 4);
    const std::size_t pixelAt = dataset.find(pixelTag + "OW");
    ASSERT_NE(pixelAt, std::string::npos);
    // A private OB element (group 7FD1 before the pixel data, 7FE1 after it) of length 0xFFFFFFF0.
    const auto huge = [](const char* tag) { return std::string(tag, 4) + std::string("OB\0\0\xf0\xff\xff\xff", 8) + std::string(16, '\0'); };
    for (const auto& damaged : {dataset.substr(0, pixelAt) + huge("\xd1\x7f\x10\x00") + dataset.substr(pixelAt),
                                dataset + huge("\xe1\x7f\x10\x00")}) {
        writeFile(dir / "ct" / "IM2", file.substr(0, datasetAt) + rawDeflate(damaged, false));
        expectFailure(dir, dir / "ct", {}, 1, {"damaged or truncated DICOM file", "premature end"}, dir / "ct" / "IM2", 1024);
    }
    // Deflated data cut short, or not deflate at all.
    writeFile(dir / "ct" / "IM2", file.substr(0, file.size() - 40));
    expectFailure(dir, dir / "ct", {}, 1, {"deflated dataset cut short"}, dir / "ct" / "IM2");
    writeFile(dir / "ct" / "IM2", file.substr(0, datasetAt) + std::string(300, '\x07'));
    expectFailure(dir, dir / "ct", {}, 1, {"damaged deflated dataset"}, dir / "ct" / "IM2");
    // The slice as written converts, in the same address space.
    writeFile(dir / "ct" / "IM2", file);
    const auto r = raw2vdbWithMemoryLimit({(dir / "ct").string(), "-o", (dir / "ct.vdb").string()}, dir.path, 1024);
    ASSERT_EQ(r.code, 0) << r.err;
    expectSeriesGrid(*readVdb(dir / "ct.vdb"), s);
}

TEST(StackBadInput, FolderWithNoImage)
{
    TempDir dir;
    fs::create_directories(dir / "empty");
    expectFailure(dir, dir / "empty", {}, 1, {"no image"}, dir / "empty");
    fs::create_directories(dir / "docs");
    writeFile(dir / "docs" / "README.txt", "nothing to see\n");
    writeFile(dir / "docs" / "data.bin", std::string(4096, '\x01'));
    expectFailure(dir, dir / "docs", {}, 1, {"no image", "no DICOM or TIFF"}, dir / "docs");
    // DICOM objects, none of them an image.
    fs::create_directories(dir / "sr");
    DcmFileFormat ff;
    ff.getDataset()->putAndInsertString(DCM_SOPClassUID, UID_BasicTextSRStorage);
    ASSERT_TRUE(ff.saveFile((dir / "sr" / "SR1").c_str(), EXS_LittleEndianExplicit).good());
    expectFailure(dir, dir / "sr", {}, 1, {"no image"}, dir / "sr");
    // A folder that does not exist.
    expectFailure(dir, dir / "nowhere.tif", {}, 1, {"cannot open"}, dir / "nowhere.tif");
}

TEST(StackBadInput, TiffTruncatedFile)
{
    TempDir dir;
    TiffSpec t;
    writeTiffStack(dir / "s.tif", t);
    const std::string bytes = readFile(dir / "s.tif");
    // libtiff writes each page's pixels, then its directory: a cut at 60% loses the later pages'
    // directories, so the chain points past the end of the file.
    writeFile(dir / "cut.tif", bytes.substr(0, bytes.size() * 6 / 10));
    expectFailure(dir, dir / "cut.tif", {}, 1, {"damaged or truncated after page"}, dir / "cut.tif");
    // ImageJ's image count tells a stack that lost whole pages from one that has none.
    t.description = "ImageJ=1.54f\nimages=14\nslices=14\n";
    writeTiffStack(dir / "short.tif", t);
    expectFailure(dir, dir / "short.tif", {}, 1, {"says 14 images", "11 pages"}, dir / "short.tif");
    // Damaged pixels, directories intact: found when the page is decoded.
    t.description.clear();
    t.compression = COMPRESSION_ADOBE_DEFLATE;
    writeTiffStack(dir / "bad.tif", t);
    uint64_t offset = 0, count = 0;
    {
        TIFF* tif = TIFFOpen((dir / "bad.tif").c_str(), "r");
        ASSERT_NE(tif, nullptr);
        ASSERT_TRUE(TIFFSetDirectory(tif, 3));
        offset = TIFFGetStrileOffset(tif, 0);
        count = TIFFGetStrileByteCount(tif, 0);
        TIFFClose(tif);
    }
    std::string damaged = readFile(dir / "bad.tif");
    ASSERT_LT(offset + count, damaged.size());
    for (uint64_t i = 2; i < count; ++i) damaged[offset + i] = char(0xA5 ^ i);
    writeFile(dir / "bad.tif", damaged);
    expectFailure(dir, dir / "bad.tif", {}, 1, {"page 4", "strip 0", "libtiff"}, dir / "bad.tif");
}

TEST(StackBadInput, TiffMixedSizesAndTypes)
{
    TempDir dir;
    TiffSpec t;
    writeTiffStack(dir / "sizes.tif", t, [](int z, TiffSpec& p) {
        if (z == 6) p.height = 19;
    });
    expectFailure(dir, dir / "sizes.tif", {}, 1, {"page 7", "mixed sizes", "21x19", "21x18"}, dir / "sizes.tif");
    writeTiffStack(dir / "types.tif", t, [](int z, TiffSpec& p) {
        if (z == 2) p.bits = 8;
    });
    expectFailure(dir, dir / "types.tif", {}, 1, {"page 3", "mixed types", "8-bit unsigned", "16-bit unsigned"}, dir / "types.tif");

    // In a folder of slices the odd file is named.
    fs::create_directories(dir / "f");
    for (int z = 0; z < 5; ++z) {
        TiffSpec p = t;
        if (z == 3) p.width = 30;
        writeTiffPage(dir / "f" / ("z" + std::to_string(z) + ".tif"), p, z);
    }
    expectFailure(dir, dir / "f", {}, 1, {"mixed sizes", "30x18"}, dir / "f" / "z3.tif");
}

TEST(StackBadInput, TiffUnsupportedPixelsAndHyperstacks)
{
    TempDir dir;
    TiffSpec rgb;
    rgb.bits = 8;
    rgb.samples = 3;
    writeTiffStack(dir / "rgb.tif", rgb);
    expectFailure(dir, dir / "rgb.tif", {}, 1, {"3 samples per pixel"}, dir / "rgb.tif page 1");
    TiffSpec hyper;
    hyper.description = "ImageJ=1.54f\nimages=12\nchannels=2\nslices=6\nhyperstack=true\n";
    hyper.pages = 12;
    writeTiffStack(dir / "hyper.tif", hyper);
    expectFailure(dir, dir / "hyper.tif", {}, 1, {"hyperstack", "2 channels"}, dir / "hyper.tif");
    // --series is for DICOM folders.
    writeTiffStack(dir / "plain.tif", TiffSpec{});
    expectFailure(dir, dir / "plain.tif", {"--series", "1.2.3"}, 1, {"--series"}, dir / "plain.tif");
}

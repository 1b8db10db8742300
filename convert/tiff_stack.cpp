#include "tiff_stack.h"

#include <tiffio.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

namespace vdb_isosimp {

namespace {

/// libtiff's messages go to the file's own handler (libtiff >= 4.5), never to stderr: the first
/// error is kept for the RawInputError, warnings (unknown tags, ...) are dropped.
int keepFirstError(TIFF* tif, void* user, const char* module, const char* fmt, va_list ap)
{
    auto* error = static_cast<std::string*>(user);
    if (error->empty()) {
        char buf[512];
        std::vsnprintf(buf, sizeof buf, fmt, ap);
        std::string text = buf;
        // The message names the file again ("<path>: Can not read ..."); the RawInputError already does.
        const char* name = tif ? TIFFFileName(tif) : nullptr;
        const std::string prefix = name ? std::string(name) + ": " : std::string();
        if (!prefix.empty() && text.compare(0, prefix.size(), prefix) == 0) text.erase(0, prefix.size());
        *error = (module && *module && (!name || std::strcmp(module, name) != 0) ? std::string(module) + ": " : std::string()) + text;
    }
    return 1;
}

int dropWarning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

/// An open TIFF file (read, not memory-mapped: mapped pages would count as resident memory).
class TiffFile {
public:
    explicit TiffFile(const std::string& path) : mPath(path)
    {
        TIFFOpenOptions* opts = TIFFOpenOptionsAlloc();
        TIFFOpenOptionsSetErrorHandlerExtR(opts, &keepFirstError, &mError);
        TIFFOpenOptionsSetWarningHandlerExtR(opts, &dropWarning, nullptr);
        mTif = TIFFOpenExt(path.c_str(), "rm", opts);
        TIFFOpenOptionsFree(opts);
        if (!mTif) throw RawInputError(path, "cannot read as TIFF (libtiff: " + (mError.empty() ? std::string("open failed") : mError) + ")");
    }
    ~TiffFile()
    {
        if (mTif) TIFFClose(mTif);
    }
    TiffFile(const TiffFile&) = delete;
    TiffFile& operator=(const TiffFile&) = delete;

    TIFF* get() const { return mTif; }
    const std::string& path() const { return mPath; }
    /// The first error libtiff reported, taken (cleared).
    std::string takeError()
    {
        std::string e;
        e.swap(mError);
        return e;
    }

private:
    std::string mPath;
    std::string mError;
    TIFF* mTif = nullptr;
};

struct PageFormat {
    uint32_t width = 0, height = 0;
    uint16_t bits = 0, samples = 1, sampleFormat = SAMPLEFORMAT_UINT;

    bool operator!=(const PageFormat& o) const
    {
        return width != o.width || height != o.height || bits != o.bits || samples != o.samples || sampleFormat != o.sampleFormat;
    }
    std::string sizeText() const { return std::to_string(width) + "x" + std::to_string(height); }
    std::string typeText() const
    {
        const char* kind = sampleFormat == SAMPLEFORMAT_IEEEFP ? "float" : sampleFormat == SAMPLEFORMAT_INT ? "signed" : "unsigned";
        std::string t = std::to_string(bits) + "-bit " + kind;
        if (samples != 1) t += " x " + std::to_string(samples) + " samples";
        return t;
    }
};

bool isReducedCopy(TIFF* tif)
{
    uint32_t type = 0;
    return TIFFGetField(tif, TIFFTAG_SUBFILETYPE, &type) == 1 && (type & FILETYPE_REDUCEDIMAGE) != 0;
}

PageFormat readFormat(TIFF* tif)
{
    PageFormat f;
    TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &f.width);
    TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &f.height);
    TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &f.bits);
    TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &f.samples);
    TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &f.sampleFormat);
    if (f.sampleFormat == SAMPLEFORMAT_VOID) f.sampleFormat = SAMPLEFORMAT_UINT;
    return f;
}

/// What the voxels are, or a message saying why not.
ScalarType scalarTypeOf(const PageFormat& f, const std::string& where)
{
    if (f.width == 0 || f.height == 0) throw RawInputError(where, "image of size " + f.sizeText());
    if (f.samples != 1)
        throw RawInputError(where, std::to_string(f.samples) + " samples per pixel (colour?): only one sample per pixel is read");
    if (f.sampleFormat == SAMPLEFORMAT_UINT || f.sampleFormat == SAMPLEFORMAT_INT) {
        const bool s = f.sampleFormat == SAMPLEFORMAT_INT;
        switch (f.bits) {
        case 8: return s ? ScalarType::I8 : ScalarType::U8;
        case 16: return s ? ScalarType::I16 : ScalarType::U16;
        case 32: return s ? ScalarType::I32 : ScalarType::U32;
        default: break;
        }
    } else if (f.sampleFormat == SAMPLEFORMAT_IEEEFP) {
        if (f.bits == 32) return ScalarType::F32;
        if (f.bits == 64) return ScalarType::F64;
    }
    throw RawInputError(where, "unsupported sample type " + f.typeText() + " (8/16/32-bit integers, 32/64-bit floats)");
}

std::string baseName(const std::string& path)
{
    const auto slash = path.find_last_of('/');
    return slash == std::string::npos ? path : path.substr(slash + 1);
}

std::string pageName(std::size_t page) { return "page " + std::to_string(page + 1); }

/// Reads the current directory's image into dst (height rows of width values, host byte order).
void readPage(TiffFile& file, const PageFormat& f, unsigned char* dst, const std::string& where)
{
    TIFF* tif = file.get();
    const std::size_t bytes = f.bits / 8;
    const std::size_t rowBytes = static_cast<std::size_t>(f.width) * bytes;
    const auto fail = [&](const std::string& what) {
        const std::string e = file.takeError();
        return RawInputError(file.path(), where + ": " + what + (e.empty() ? "" : " (libtiff: " + e + ")"));
    };
    if (TIFFIsTiled(tif)) {
        uint32_t tw = 0, th = 0;
        TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tw);
        TIFFGetField(tif, TIFFTAG_TILELENGTH, &th);
        const tmsize_t tileSize = TIFFTileSize(tif);
        if (tw == 0 || th == 0 || tileSize < static_cast<tmsize_t>(uint64_t(tw) * th * bytes)) throw fail("invalid tile layout");
        std::vector<unsigned char> tile(static_cast<std::size_t>(tileSize));
        for (uint32_t y0 = 0; y0 < f.height; y0 += th)
            for (uint32_t x0 = 0; x0 < f.width; x0 += tw) {
                if (TIFFReadTile(tif, tile.data(), x0, y0, 0, 0) < 0)
                    throw fail("tile at " + std::to_string(x0) + "," + std::to_string(y0) + " cannot be read");
                const uint32_t rows = std::min(th, f.height - y0), cols = std::min(tw, f.width - x0);
                for (uint32_t r = 0; r < rows; ++r)
                    std::memcpy(dst + (static_cast<std::size_t>(y0 + r) * f.width + x0) * bytes, tile.data() + std::size_t(r) * tw * bytes,
                                cols * bytes);
            }
        return;
    }
    uint32_t rps = 0;
    TIFFGetFieldDefaulted(tif, TIFFTAG_ROWSPERSTRIP, &rps);
    if (rps == 0 || rps > f.height) rps = f.height;
    const uint32_t strips = TIFFNumberOfStrips(tif);
    if (uint64_t(strips) * rps < f.height) throw fail(std::to_string(strips) + " strips of " + std::to_string(rps) + " rows for " +
                                                      std::to_string(f.height) + " rows");
    for (uint32_t s = 0; s < strips; ++s) {
        const uint64_t row0 = uint64_t(s) * rps;
        if (row0 >= f.height) break;
        const uint64_t rows = std::min<uint64_t>(rps, f.height - row0);
        const tmsize_t want = static_cast<tmsize_t>(rows * rowBytes);
        const tmsize_t got = TIFFReadEncodedStrip(tif, s, dst + row0 * rowBytes, want);
        if (got != want)
            throw fail("strip " + std::to_string(s) + (got < 0 ? std::string(" cannot be read") :
                                                             " holds " + std::to_string(got) + " bytes where " + std::to_string(want) +
                                                                 " are needed (truncated?)"));
    }
}

/// ImageJ's description: "ImageJ=1.54f\nimages=120\nslices=120\nunit=micron\nspacing=4.0\n...".
struct ImageJInfo {
    bool present = false;
    long images = 0, slices = 0, frames = 0, channels = 0;
    std::string unit;
    double spacing = 0;
};

ImageJInfo parseImageJ(TIFF* tif)
{
    ImageJInfo ij;
    const char* desc = nullptr;
    if (TIFFGetField(tif, TIFFTAG_IMAGEDESCRIPTION, &desc) != 1 || !desc || std::strncmp(desc, "ImageJ=", 7) != 0) return ij;
    ij.present = true;
    std::istringstream in(desc);
    std::string line;
    while (std::getline(in, line)) {
        const auto eq = line.find('=');
        if (eq == std::string::npos) continue;
        const std::string key = line.substr(0, eq), value = line.substr(eq + 1);
        const auto number = [&] { return std::strtod(value.c_str(), nullptr); };
        if (key == "images") ij.images = std::atol(value.c_str());
        else if (key == "slices") ij.slices = std::atol(value.c_str());
        else if (key == "frames") ij.frames = std::atol(value.c_str());
        else if (key == "channels") ij.channels = std::atol(value.c_str());
        else if (key == "unit") ij.unit = value;
        else if (key == "spacing") ij.spacing = number();
    }
    return ij;
}

/// Micrometres per ImageJ unit (no unit or "pixel": taken as µm).
double micronsPer(const std::string& unit)
{
    if (unit == "nm" || unit == "nanometer") return 1e-3;
    if (unit == "mm" || unit == "millimeter") return 1e3;
    if (unit == "cm" || unit == "centimeter") return 1e4;
    if (unit == "m" || unit == "meter" || unit == "metre") return 1e6;
    if (unit == "inch" || unit == "in") return 25400;
    return 1;  // micron, um, µm, \u00B5m, pixel, none
}

/// Voxel size in µm from the first page's tags (see tiff_stack.h); `how` says where it came from.
std::array<double, 3> readSpacing(TIFF* tif, const ImageJInfo& ij, std::string& how)
{
    float xr = 0, yr = 0;
    uint16_t unit = RESUNIT_INCH;
    const bool hasRes = TIFFGetField(tif, TIFFTAG_XRESOLUTION, &xr) == 1 && TIFFGetField(tif, TIFFTAG_YRESOLUTION, &yr) == 1 &&
                        xr > 0 && yr > 0 && std::isfinite(xr) && std::isfinite(yr);
    TIFFGetFieldDefaulted(tif, TIFFTAG_RESOLUTIONUNIT, &unit);
    std::array<double, 3> sp{{1, 1, 1}};
    if (ij.present) {
        const double f = micronsPer(ij.unit);
        if (hasRes) {
            sp[0] = f / xr;
            sp[1] = f / yr;
        }
        sp[2] = ij.spacing > 0 && std::isfinite(ij.spacing) ? f * ij.spacing : f;
        how = "ImageJ" + (ij.unit.empty() ? std::string() : ", unit " + ij.unit);
    } else if (hasRes && unit == RESUNIT_CENTIMETER) {
        sp[0] = 1e4 / xr;
        sp[1] = 1e4 / yr;
        how = "resolution in pixels/cm, z unknown";
    } else {
        how = "no spacing in the file";
    }
    return sp;
}

class TiffStack final : public SliceSource {
public:
    /// Multi-page: one file, the directory offsets of its pages. Folder: one file per slice.
    TiffStack(std::unique_ptr<TiffFile> file, std::vector<uint64_t> pageOffsets, PageFormat format)
        : mFile(std::move(file)), mOffsets(std::move(pageOffsets)), mFormat(format) {}
    TiffStack(std::vector<std::string> files, PageFormat format) : mFiles(std::move(files)), mFormat(format) {}

    RawVolumeInfo& info() { return mInfo; }
    void setSpacingSource(std::string how) { mHow = std::move(how); }

    void readSlices(uint64_t z0, uint64_t n, unsigned char* dst) override
    {
        const std::size_t sliceBytes = std::size_t(mFormat.width) * mFormat.height * (mFormat.bits / 8);
        if (mFile) {
            for (uint64_t k = 0; k < n; ++k) {
                const std::size_t page = static_cast<std::size_t>(z0 + k);
                if (!TIFFSetSubDirectory(mFile->get(), mOffsets[page])) {
                    const std::string e = mFile->takeError();
                    throw RawInputError(mFile->path(), pageName(page) + ": directory cannot be read again" +
                                                           (e.empty() ? "" : " (libtiff: " + e + ")"));
                }
                readPage(*mFile, mFormat, dst + k * sliceBytes, pageName(page));
            }
            return;
        }
        tbb::parallel_for(uint64_t(0), n, [&](uint64_t k) {
            TiffFile file(mFiles[static_cast<std::size_t>(z0 + k)]);
            while (isReducedCopy(file.get()) && TIFFReadDirectory(file.get())) {}
            const PageFormat f = readFormat(file.get());
            if (f != mFormat) throw RawInputError(file.path(), "changed while it was read");
            readPage(file, mFormat, dst + k * sliceBytes, "page 1");
        });
    }

    std::string describe() const override
    {
        std::string d = mFile ? "TIFF stack, " + std::to_string(mOffsets.size()) + " pages"
                              : "TIFF folder, " + std::to_string(mFiles.size()) + " files";
        return d + ", " + mFormat.typeText() + ", spacing: " + mHow;
    }

private:
    std::unique_ptr<TiffFile> mFile;
    std::vector<uint64_t> mOffsets;
    std::vector<std::string> mFiles;
    PageFormat mFormat;
    std::string mHow;
};

void fillInfo(RawVolumeInfo& info, VolumeFormat format, const std::string& input, const std::string& dataFile,
              const PageFormat& f, ScalarType type, uint64_t slices, const std::array<double, 3>& spacing)
{
    info.format = format;
    info.headerFile = input;
    info.dataFile = dataFile;
    info.dims = {{f.width, f.height, slices}};
    info.type = type;
    info.byteOrder = hostByteOrder();
    info.spacing = spacing;
    validateDims(input, info.dims, type);
}

} // namespace

bool looksLikeTiff(const std::string& path)
{
    std::ifstream f(path, std::ios::binary);
    unsigned char b[4] = {0, 0, 0, 0};
    f.read(reinterpret_cast<char*>(b), 4);
    if (f.gcount() != 4) return false;
    return (b[0] == 'I' && b[1] == 'I' && (b[2] == 42 || b[2] == 43) && b[3] == 0) ||
           (b[0] == 'M' && b[1] == 'M' && b[2] == 0 && (b[3] == 42 || b[3] == 43));
}

std::unique_ptr<SliceSource> openTiffFile(const std::string& path)
{
    auto file = std::make_unique<TiffFile>(path);
    TIFF* tif = file->get();
    while (isReducedCopy(tif)) {
        if (!TIFFReadDirectory(tif)) throw RawInputError(path, "no image: only reduced-resolution copies");
    }
    const PageFormat first = readFormat(tif);
    const ScalarType type = scalarTypeOf(first, path + " " + pageName(0));
    const ImageJInfo ij = parseImageJ(tif);
    std::string how;
    const std::array<double, 3> spacing = readSpacing(tif, ij, how);
    if (ij.present && (ij.channels > 1 || ij.frames > 1))
        throw RawInputError(path, "ImageJ hyperstack with " + std::to_string(std::max(1L, ij.channels)) + " channels and " +
                                      std::to_string(std::max(1L, ij.frames)) +
                                      " frames: only single-channel, single-frame stacks are volumes (split them in Fiji first)");

    // Walk every page up front: sizes and types must agree, and a damaged directory chain is found now.
    std::vector<uint64_t> offsets;
    std::size_t index = 0;
    do {
        if (isReducedCopy(tif)) continue;
        const PageFormat f = readFormat(tif);
        if (f.sizeText() != first.sizeText())
            throw RawInputError(path, pageName(index) + ": mixed sizes: " + f.sizeText() + " where page 1 is " + first.sizeText());
        if (f != first)
            throw RawInputError(path, pageName(index) + ": mixed types: " + f.typeText() + " where page 1 is " + first.typeText());
        offsets.push_back(TIFFCurrentDirOffset(tif));
        ++index;
    } while (TIFFReadDirectory(tif));
    const std::string error = file->takeError();
    if (!error.empty())
        throw RawInputError(path, "damaged or truncated after " + pageName(index - 1) + " (libtiff: " + error + ")");
    if (ij.present && ij.images > 0 && static_cast<std::size_t>(ij.images) != offsets.size())
        throw RawInputError(path, "ImageJ's description says " + std::to_string(ij.images) + " images, the file holds " +
                                      std::to_string(offsets.size()) + " pages (truncated, or an ImageJ file over 4 GiB, "
                                      "which has one directory for all: save it as a folder of slices instead)");

    const uint64_t slices = offsets.size();
    auto src = std::make_unique<TiffStack>(std::move(file), std::move(offsets), first);
    fillInfo(src->info(), VolumeFormat::Tiff, path, path, first, type, slices, spacing);
    src->setSpacingSource(how);
    return src;
}

std::unique_ptr<SliceSource> openTiffFolder(const std::string& folder, std::vector<std::string> files)
{
    std::sort(files.begin(), files.end(), naturalLess);
    PageFormat first;
    ScalarType type = ScalarType::U8;
    std::array<double, 3> spacing{{1, 1, 1}};
    std::string how;
    for (std::size_t i = 0; i < files.size(); ++i) {
        TiffFile file(files[i]);
        TIFF* tif = file.get();
        while (isReducedCopy(tif)) {
            if (!TIFFReadDirectory(tif)) throw RawInputError(files[i], "no image: only reduced-resolution copies");
        }
        const PageFormat f = readFormat(tif);
        if (i == 0) {
            first = f;
            type = scalarTypeOf(f, files[i]);
            spacing = readSpacing(tif, parseImageJ(tif), how);
        } else if (f.sizeText() != first.sizeText()) {
            throw RawInputError(files[i], "mixed sizes: " + f.sizeText() + " where " + baseName(files[0]) + " is " + first.sizeText());
        } else if (f != first) {
            throw RawInputError(files[i], "mixed types: " + f.typeText() + " where " + baseName(files[0]) + " is " + first.typeText());
        }
        std::size_t pages = 1;
        while (TIFFReadDirectory(tif))
            if (!isReducedCopy(tif)) ++pages;
        const std::string error = file.takeError();
        if (!error.empty()) throw RawInputError(files[i], "damaged or truncated (libtiff: " + error + ")");
        if (pages > 1)
            throw RawInputError(files[i], std::to_string(pages) + " pages: a folder is read as single-page slices "
                                          "(convert a multi-page file on its own)");
    }
    const uint64_t slices = files.size();
    const std::string firstFile = files.front();
    auto src = std::make_unique<TiffStack>(std::move(files), first);
    fillInfo(src->info(), VolumeFormat::Tiff, folder, firstFile, first, type, slices, spacing);
    src->setSpacingSource(how);
    return src;
}

} // namespace vdb_isosimp

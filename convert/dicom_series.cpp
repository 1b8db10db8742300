#include "dicom_series.h"

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dccodec.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcdict.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcistrmf.h>
#include <dcmtk/dcmdata/dcmetinf.h>
#include <dcmtk/dcmdata/dcrledrg.h>
#include <dcmtk/dcmdata/dcxfer.h>
#include <dcmtk/dcmjpeg/djdecode.h>
#include <dcmtk/dcmjpls/djdecode.h>
#include <dcmtk/oflog/oflog.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <vector>

#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

namespace vdb_isosimp {

namespace {

/// DCMTK's decoders are registered once per process; its own logging is silenced (every problem
/// reaches the user as one RawInputError line instead).
void initDcmtk()
{
    static std::once_flag once;
    std::call_once(once, [] {
        OFLog::getLogger("dcmtk").setLogLevel(OFLogger::OFF_LOG_LEVEL);
        DJDecoderRegistration::registerCodecs();
        DJLSDecoderRegistration::registerCodecs();
        DcmRLEDecoderRegistration::registerCodecs();
    });
}

/// One image file of a series: what its header says (pixel data not read).
struct DicomSlice {
    std::string path;
    std::string series, seriesDescription;
    uint16_t rows = 0, cols = 0, bitsAllocated = 0, bitsStored = 0, highBit = 0, pixelRep = 0, samples = 1;
    long frames = 1;
    std::array<double, 3> ipp{{0, 0, 0}};
    std::array<double, 6> iop{{1, 0, 0, 0, 1, 0}};
    std::array<double, 2> pixelSpacing{{1, 1}};
    bool hasIpp = false, hasIop = false, hasSpacing = false;
    double slope = 1, intercept = 0, thickness = 0, spacingBetween = 0;
    E_TransferSyntax xfer = EXS_Unknown;
    double position = 0;  // along the slice normal
};

std::string xferText(E_TransferSyntax xfer)
{
    const DcmXfer x(xfer);
    return std::string(x.getXferName()) + " (" + x.getXferID() + ")";
}

std::string fileName(const std::string& path)
{
    const auto slash = path.find_last_of('/');
    return slash == std::string::npos ? path : path.substr(slash + 1);
}

uint64_t fileSize(const std::string& path)
{
    struct stat st {};
    return ::stat(path.c_str(), &st) == 0 ? static_cast<uint64_t>(st.st_size) : 0;
}

template <std::size_t N>
bool getDoubles(DcmDataset& ds, const DcmTagKey& tag, std::array<double, N>& out)
{
    for (std::size_t i = 0; i < N; ++i) {
        Float64 v = 0;
        if (ds.findAndGetFloat64(tag, v, static_cast<unsigned long>(i)).bad() || !std::isfinite(v)) return false;
        out[i] = v;
    }
    return true;
}

double getDouble(DcmDataset& ds, const DcmTagKey& tag, double fallback)
{
    Float64 v = 0;
    return ds.findAndGetFloat64(tag, v).good() && std::isfinite(v) ? v : fallback;
}

uint16_t getU16(DcmDataset& ds, const DcmTagKey& tag, uint16_t fallback)
{
    Uint16 v = 0;
    return ds.findAndGetUint16(tag, v).good() ? v : fallback;
}

/// One DICOM file, loaded by DCMTK from a file it can seek in. A deflated dataset (Deflated Explicit VR
/// Little Endian) is inflated first into an in-memory file: from a compressed stream DCMTK reads each
/// value at once into a buffer of the value's declared length, so one damaged length field claims up
/// to 4 GiB, whereas from a plain file it leaves large values on disk until they are asked for and
/// checks each length against the file's size.
class DicomFile {
public:
    /// No single-frame slice inflates to more: a larger result is damage or a decompression bomb.
    static constexpr uint64_t kMaxInflatedBytes = uint64_t(1) << 30;

    explicit DicomFile(const std::string& path) : mPath(path)
    {
        DcmInputFileStream in(path.c_str());
        if (in.status().bad()) return;  // loading names the problem
        DcmMetaInfo meta;
        meta.transferInit();
        const OFCondition c = meta.read(in, EXS_Unknown, EGL_noChange, DCM_MaxReadLength);
        meta.transferEnd();
        OFString uid;
        if (c.bad() || meta.findAndGetOFString(DCM_TransferSyntaxUID, uid).bad() ||
            DcmXfer(uid.c_str()).getXfer() != EXS_DeflatedLittleEndianExplicit)
            return;
        inflateDataset(static_cast<uint64_t>(in.tell()));
    }
    ~DicomFile()
    {
        if (mInflated >= 0) ::close(mInflated);
    }
    DicomFile(const DicomFile&) = delete;
    DicomFile& operator=(const DicomFile&) = delete;

    /// Loads the whole file, or with `headerOnly` everything before the pixel data.
    OFCondition load(DcmFileFormat& ff, bool headerOnly) const
    {
        const bool inflated = mInflated >= 0;
        const std::string path = inflated ? "/proc/self/fd/" + std::to_string(mInflated) : mPath;
        const E_TransferSyntax xfer = inflated ? EXS_LittleEndianExplicit : EXS_Unknown;
        const E_FileReadMode mode = inflated ? ERM_dataset : ERM_autoDetect;
        return headerOnly ? ff.loadFileUntilTag(path.c_str(), xfer, EGL_noChange, DCM_MaxReadLength, mode, DCM_PixelData)
                          : ff.loadFile(path.c_str(), xfer, EGL_noChange, DCM_MaxReadLength, mode);
    }

    /// The transfer syntax the file is stored in, as `load`'s dataset cannot tell for an inflated file.
    E_TransferSyntax storedXfer(const DcmDataset& loaded) const
    {
        return mInflated >= 0 ? EXS_DeflatedLittleEndianExplicit : loaded.getOriginalXfer();
    }

private:
    /// Inflates the raw deflate stream after the meta header (at `offset`) into an in-memory file.
    void inflateDataset(uint64_t offset)
    {
        // A deflate stream is at most its data plus 5 bytes per 64 KiB block: a longer one inflates past the limit.
        if (fileSize(mPath) > offset + kMaxInflatedBytes + kMaxInflatedBytes / 1024)
            throw RawInputError(mPath, "deflated dataset larger than 1 GiB: no single image");
        std::ifstream f(mPath, std::ios::binary);
        f.seekg(static_cast<std::streamoff>(offset));
        const std::string packed((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
        z_stream z{};
        if (inflateInit2(&z, -MAX_WBITS) != Z_OK) throw RawInputError(mPath, "cannot inflate the deflated dataset (zlib)");
        const int fd = ::memfd_create("vdb_isosimp-dicom", MFD_CLOEXEC);
        if (fd < 0) {
            inflateEnd(&z);
            throw RawInputError(mPath, std::string("cannot inflate the deflated dataset: ") + std::strerror(errno));
        }
        z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(packed.data()));
        z.avail_in = static_cast<uInt>(packed.size());
        std::vector<unsigned char> chunk(1 << 20);
        uint64_t total = 0;
        int rc = Z_OK;
        std::string problem;
        while (rc == Z_OK && problem.empty()) {
            z.next_out = chunk.data();
            z.avail_out = static_cast<uInt>(chunk.size());
            rc = inflate(&z, Z_NO_FLUSH);
            const std::size_t got = chunk.size() - z.avail_out;
            total += got;
            if (rc != Z_OK && rc != Z_STREAM_END)
                problem = rc == Z_BUF_ERROR ? std::string("deflated dataset cut short")
                                            : std::string("damaged deflated dataset (zlib: ") + (z.msg ? z.msg : "error") + ")";
            else if (total > kMaxInflatedBytes)
                problem = "deflated dataset inflates to more than 1 GiB: damaged, or no single image";
            else if (got > 0 && ::write(fd, chunk.data(), got) != static_cast<ssize_t>(got))
                problem = std::string("cannot inflate the deflated dataset: ") + std::strerror(errno);
        }
        inflateEnd(&z);
        if (!problem.empty()) {
            ::close(fd);
            throw RawInputError(mPath, problem);
        }
        mInflated = fd;
    }

    std::string mPath;
    int mInflated = -1;  // the in-memory file holding the inflated dataset, if the file is deflated
};

/// Reads the header of `path` up to the pixel data. Returns false for a DICOM object that is no image
/// (no Rows/Columns: DICOMDIR, structured reports, presentation states).
bool readHeader(const std::string& path, DicomSlice& s)
{
    const DicomFile file(path);
    DcmFileFormat ff;
    const OFCondition c = file.load(ff, true);
    if (c.bad()) throw RawInputError(path, std::string("damaged or truncated DICOM file (DCMTK: ") + c.text() + ")");
    DcmDataset& ds = *ff.getDataset();
    if (!ds.tagExists(DCM_Rows) || !ds.tagExists(DCM_Columns)) return false;
    s.path = path;
    s.xfer = file.storedXfer(ds);
    OFString str;
    if (ds.findAndGetOFString(DCM_SeriesInstanceUID, str).good()) s.series = str.c_str();
    if (ds.findAndGetOFString(DCM_SeriesDescription, str).good()) s.seriesDescription = str.c_str();
    s.rows = getU16(ds, DCM_Rows, 0);
    s.cols = getU16(ds, DCM_Columns, 0);
    s.bitsAllocated = getU16(ds, DCM_BitsAllocated, 0);
    s.bitsStored = getU16(ds, DCM_BitsStored, s.bitsAllocated);
    s.highBit = getU16(ds, DCM_HighBit, static_cast<uint16_t>(s.bitsStored ? s.bitsStored - 1 : 0));
    s.pixelRep = getU16(ds, DCM_PixelRepresentation, 0);
    s.samples = getU16(ds, DCM_SamplesPerPixel, 1);
    if (ds.findAndGetOFString(DCM_NumberOfFrames, str).good()) s.frames = std::atol(str.c_str());
    s.hasIpp = getDoubles(ds, DCM_ImagePositionPatient, s.ipp);
    s.hasIop = getDoubles(ds, DCM_ImageOrientationPatient, s.iop);
    s.hasSpacing = getDoubles(ds, DCM_PixelSpacing, s.pixelSpacing);
    s.slope = getDouble(ds, DCM_RescaleSlope, 1.0);
    s.intercept = getDouble(ds, DCM_RescaleIntercept, 0.0);
    s.thickness = getDouble(ds, DCM_SliceThickness, 0.0);
    s.spacingBetween = getDouble(ds, DCM_SpacingBetweenSlices, 0.0);
    return true;
}

std::string sizeText(const DicomSlice& s) { return std::to_string(s.cols) + "x" + std::to_string(s.rows); }

std::string typeText(const DicomSlice& s)
{
    return std::to_string(s.bitsStored) + " of " + std::to_string(s.bitsAllocated) + " bits " +
           (s.pixelRep ? "signed" : "unsigned");
}

/// Checks what a slice must say on its own to be part of a volume.
void checkSlice(const DicomSlice& s)
{
    if (s.rows == 0 || s.cols == 0) throw RawInputError(s.path, "image of size " + sizeText(s));
    if (s.samples != 1)
        throw RawInputError(s.path, std::to_string(s.samples) + " samples per pixel (colour image): only greyscale images are volumes");
    if (s.frames > 1)
        throw RawInputError(s.path, "multi-frame image (" + std::to_string(s.frames) +
                                        " frames): only series of single-frame images are read");
    if (s.bitsAllocated != 8 && s.bitsAllocated != 16 && s.bitsAllocated != 32)
        throw RawInputError(s.path, "unsupported BitsAllocated " + std::to_string(s.bitsAllocated) + " (8, 16 or 32)");
    if (s.bitsStored == 0 || s.bitsStored > s.bitsAllocated || s.highBit >= s.bitsAllocated || s.highBit + 1 < s.bitsStored)
        throw RawInputError(s.path, "inconsistent BitsStored " + std::to_string(s.bitsStored) + " / HighBit " +
                                        std::to_string(s.highBit) + " for BitsAllocated " + std::to_string(s.bitsAllocated));
    if (s.pixelRep > 1) throw RawInputError(s.path, "invalid PixelRepresentation " + std::to_string(s.pixelRep));
    if (!s.hasIpp) throw RawInputError(s.path, "no ImagePositionPatient (0020,0032): the slice cannot be placed");
    if (!s.hasIop) throw RawInputError(s.path, "no ImageOrientationPatient (0020,0037): the slice cannot be placed");
    if (!std::isfinite(s.slope) || s.slope == 0 || !std::isfinite(s.intercept))
        throw RawInputError(s.path, "invalid RescaleSlope/RescaleIntercept");
}

bool near(double a, double b, double tol) { return std::fabs(a - b) <= tol; }

using Vec3 = std::array<double, 3>;
Vec3 cross(const Vec3& a, const Vec3& b)
{
    return {{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}};
}
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }

ScalarType storedType(const DicomSlice& s)
{
    switch (s.bitsAllocated) {
    case 8: return s.pixelRep ? ScalarType::I8 : ScalarType::U8;
    case 16: return s.pixelRep ? ScalarType::I16 : ScalarType::U16;
    default: return s.pixelRep ? ScalarType::I32 : ScalarType::U32;
    }
}

class DicomSeries final : public SliceSource {
public:
    DicomSeries(std::string folder, std::vector<DicomSlice> slices, bool perSliceRescale)
        : mFolder(std::move(folder)), mSlices(std::move(slices)), mPerSliceRescale(perSliceRescale)
    {
        const DicomSlice& f = mSlices.front();
        mShift = f.highBit + 1 - f.bitsStored;
        mMasked = f.bitsStored < f.bitsAllocated;
    }

    void readSlices(uint64_t z0, uint64_t n, unsigned char* dst) override
    {
        const std::size_t sliceBytes = static_cast<std::size_t>(mInfo.dims[0] * mInfo.dims[1] * scalarSize(mInfo.type));
        // Files decode independently (DCMTK's codec list is locked for reading), so the slices of a slab
        // are decoded in parallel while the converter turns the previous slab into leaves.
        tbb::parallel_for(uint64_t(0), n, [&](uint64_t k) { readSlice(mSlices[z0 + k], dst + k * sliceBytes); });
    }

    std::string describe() const override
    {
        E_TransferSyntax xfer = mSlices.front().xfer;
        bool mixed = false;
        for (const auto& s : mSlices) mixed = mixed || s.xfer != xfer;
        std::string d = "DICOM series " + (mSlices.front().series.empty() ? std::string("without UID") : mSlices.front().series) +
                        ", " + std::to_string(mSlices.size()) + " files, " +
                        (mixed ? std::string("mixed transfer syntaxes") : std::string(DcmXfer(xfer).getXferName()));
        if (mPerSliceRescale) d += ", rescaled per slice";
        else if (mInfo.scale != 1 || mInfo.intercept != 0) {
            char buf[96];
            std::snprintf(buf, sizeof buf, ", value x %g %+g", mInfo.scale, mInfo.intercept);
            d += buf;
        }
        return d;
    }

    RawVolumeInfo& info() { return mInfo; }

private:
    template <typename T>
    void storeValues(const DicomSlice& s, const T* words, unsigned char* dst) const
    {
        using S = std::make_signed_t<T>;
        const std::size_t count = static_cast<std::size_t>(s.rows) * s.cols;
        const unsigned bits = s.bitsStored;
        const T mask = bits >= sizeof(T) * 8 ? T(~T(0)) : T((T(1) << bits) - 1);
        for (std::size_t i = 0; i < count; ++i) {
            T v = words[i];
            if (mMasked || mShift) v = T((v >> mShift) & mask);
            double value;
            T stored = v;
            if (s.pixelRep) {
                // Sign-extend the BitsStored-bit value.
                if (mMasked && (v >> (bits - 1)) & 1u) stored = T(v | T(~mask));
                value = static_cast<double>(static_cast<S>(stored));
            } else {
                value = static_cast<double>(stored);
            }
            if (mPerSliceRescale) {
                const float f = static_cast<float>(value * s.slope + s.intercept);
                std::memcpy(dst + i * sizeof(float), &f, sizeof(float));
            } else {
                std::memcpy(dst + i * sizeof(T), &stored, sizeof(T));
            }
        }
    }

    void readSlice(const DicomSlice& s, unsigned char* dst) const
    {
        const DicomFile file(s.path);
        DcmFileFormat ff;
        OFCondition c = file.load(ff, false);
        if (c.bad()) throw RawInputError(s.path, std::string("damaged or truncated DICOM file (DCMTK: ") + c.text() + ")");
        DcmDataset& ds = *ff.getDataset();
        const E_TransferSyntax xfer = ds.getOriginalXfer();
        if (DcmXfer(xfer).isEncapsulated()) {
            if (!DcmCodecList::canChangeCoding(xfer, EXS_LittleEndianExplicit))
                throw RawInputError(s.path, "compressed transfer syntax " + xferText(xfer) + " that DCMTK cannot decode");
            c = ds.chooseRepresentation(EXS_LittleEndianExplicit, nullptr);
            if (c.bad() || !ds.hasRepresentation(EXS_LittleEndianExplicit, nullptr))
                throw RawInputError(s.path, "compressed pixel data (" + xferText(xfer) + ") cannot be decoded (DCMTK: " + c.text() + ")");
        }
        const std::size_t count = static_cast<std::size_t>(s.rows) * s.cols;
        const std::size_t need = count * (s.bitsAllocated / 8);
        unsigned long have = 0;
        const void* words = nullptr;
        if (s.bitsAllocated == 8) {
            const Uint8* p = nullptr;
            c = ds.findAndGetUint8Array(DCM_PixelData, p, &have);
            words = p;
        } else {
            const Uint16* p = nullptr;
            c = ds.findAndGetUint16Array(DCM_PixelData, p, &have);
            have *= 2;
            words = p;
        }
        if (c.bad() || !words) throw RawInputError(s.path, std::string("no pixel data (DCMTK: ") + c.text() + ")");
        if (have < need)
            throw RawInputError(s.path, "truncated pixel data: " + sizeText(s) + " of " + std::to_string(s.bitsAllocated) + " bits needs " +
                                            std::to_string(need) + " bytes, the file holds " + std::to_string(have));
        switch (s.bitsAllocated) {
        case 8: storeValues(s, static_cast<const uint8_t*>(words), dst); break;
        case 16: storeValues(s, static_cast<const uint16_t*>(words), dst); break;
        default: {
            // 32-bit values come as pairs of 16-bit words in DCMTK's local byte order; little-endian hosts
            // only (x86, arm64), where the pairs are the values' bytes in order.
            std::vector<uint32_t> v(count);
            std::memcpy(v.data(), words, need);
            storeValues(s, v.data(), dst);
        }
        }
    }

    std::string mFolder;
    std::vector<DicomSlice> mSlices;
    bool mPerSliceRescale;
    unsigned mShift = 0;
    bool mMasked = false;
};

/// Picks the series: the one asked for, or the only one there is.
std::vector<DicomSlice> pickSeries(const std::string& folder, std::vector<DicomSlice> all, const std::string& series)
{
    std::map<std::string, std::vector<DicomSlice>> bySeries;
    for (auto& s : all) bySeries[s.series].push_back(std::move(s));
    const auto listing = [&] {
        std::string l;
        int shown = 0;
        for (const auto& [uid, slices] : bySeries) {
            if (shown++ == 6) {
                l += ", ...";
                break;
            }
            if (!l.empty()) l += ", ";
            l += (uid.empty() ? std::string("(no UID)") : uid) + ": " + std::to_string(slices.size()) + " files";
            if (!slices.front().seriesDescription.empty()) l += " '" + slices.front().seriesDescription + "'";
        }
        return l;
    };
    if (!series.empty()) {
        auto it = bySeries.find(series);
        if (it == bySeries.end())
            throw RawInputError(folder, "no image of series " + series + " (the folder holds " + listing() + ")");
        return std::move(it->second);
    }
    if (bySeries.size() > 1)
        throw RawInputError(folder, std::to_string(bySeries.size()) + " series (" + listing() + "): choose one with --series UID");
    return std::move(bySeries.begin()->second);
}

} // namespace

bool looksLikeDicom(const std::string& path)
{
    std::ifstream f(path, std::ios::binary);
    unsigned char b[132];
    f.read(reinterpret_cast<char*>(b), sizeof b);
    const std::streamsize got = f.gcount();
    if (got == 132 && std::memcmp(b + 128, "DICM", 4) == 0) return true;
    // No preamble: the dataset starts with its first element's tag, group 0002 (meta) or 0008
    // (identification, the first group of every image), little endian as every transfer syntax in use.
    if (got < 8) return false;
    const unsigned group = b[0] | (b[1] << 8);
    return group == 0x0002 || group == 0x0008;
}

std::unique_ptr<SliceSource> openDicomSeries(const std::string& folder, const std::vector<std::string>& files,
                                             const std::string& series)
{
    initDcmtk();
    if (!dcmDataDict.isDictionaryLoaded())
        throw RawInputError(folder, "DCMTK's data dictionary is not loaded (install libdcmtk17 or set DCMDICTPATH)");

    std::vector<DicomSlice> all;
    for (const auto& path : files) {
        DicomSlice s;
        if (readHeader(path, s)) all.push_back(std::move(s));
    }
    if (all.empty()) throw RawInputError(folder, "no image: the DICOM files here hold no pixel data (DICOMDIR, reports?)");
    std::vector<DicomSlice> slices = pickSeries(folder, std::move(all), series);

    // Every slice alone, then each against the first.
    for (const auto& s : slices) checkSlice(s);
    const DicomSlice& f = slices.front();
    for (const auto& s : slices) {
        if (s.rows != f.rows || s.cols != f.cols)
            throw RawInputError(s.path, "mixed sizes: " + sizeText(s) + " where " + fileName(f.path) + " is " + sizeText(f));
        if (s.bitsAllocated != f.bitsAllocated || s.bitsStored != f.bitsStored || s.highBit != f.highBit || s.pixelRep != f.pixelRep)
            throw RawInputError(s.path, "mixed types: " + typeText(s) + " where " + fileName(f.path) + " has " + typeText(f));
        for (int i = 0; i < 6; ++i)
            if (!near(s.iop[i], f.iop[i], 1e-4))
                throw RawInputError(s.path, "orientation (ImageOrientationPatient) differs from " + fileName(f.path));
        if (s.hasSpacing != f.hasSpacing || !near(s.pixelSpacing[0], f.pixelSpacing[0], 1e-4 * f.pixelSpacing[0]) ||
            !near(s.pixelSpacing[1], f.pixelSpacing[1], 1e-4 * f.pixelSpacing[1]))
            throw RawInputError(s.path, "pixel spacing differs from " + fileName(f.path));
    }

    // Directions: IOP's row and column cosines, normalised; the normal is their cross product.
    Vec3 row{{f.iop[0], f.iop[1], f.iop[2]}}, col{{f.iop[3], f.iop[4], f.iop[5]}};
    const double rn = norm(row), cn = norm(col);
    if (!(rn > 0.5 && rn < 1.5 && cn > 0.5 && cn < 1.5))
        throw RawInputError(f.path, "invalid ImageOrientationPatient: direction cosines are not unit vectors");
    for (int i = 0; i < 3; ++i) {
        row[i] /= rn;
        col[i] /= cn;
    }
    Vec3 normal = cross(row, col);
    const double nn = norm(normal);
    if (nn < 0.5) throw RawInputError(f.path, "invalid ImageOrientationPatient: row and column directions are parallel");
    for (int i = 0; i < 3; ++i) normal[i] /= nn;

    for (auto& s : slices) s.position = dot(s.ipp, normal);
    std::stable_sort(slices.begin(), slices.end(), [](const DicomSlice& a, const DicomSlice& b) {
        return a.position < b.position || (a.position == b.position && a.path < b.path);
    });

    const std::size_t n = slices.size();
    Vec3 axisK = normal;
    double spacingK = 1.0;
    if (n > 1) {
        // Each step against the median step: a missing slice shows as the one step that is twice the others.
        std::vector<double> steps(n - 1);
        for (std::size_t k = 1; k < n; ++k) steps[k - 1] = slices[k].position - slices[k - 1].position;
        std::vector<double> sorted = steps;
        std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
        const double median = sorted[sorted.size() / 2];
        for (std::size_t k = 1; k < n; ++k) {
            const double d = steps[k - 1];
            if (d < 1e-4)
                throw RawInputError(folder, fileName(slices[k - 1].path) + " and " + fileName(slices[k].path) +
                                                " are at the same position along the slice normal (several echoes, phases or "
                                                "acquisitions in one series?)");
            if (std::fabs(d - median) > 0.01 * median) {
                char buf[200];
                std::snprintf(buf, sizeof buf, "uneven slice spacing: %.4g mm from %s to %s where the other slices are %.4g mm apart",
                              d, fileName(slices[k - 1].path).c_str(), fileName(slices[k].path).c_str(), median);
                throw RawInputError(folder, std::string(buf) + " (missing slices? resampling is not supported)");
            }
        }
        // The slices' origins must lie on one line with that step (a tilted gantry shears it, which the
        // transform keeps).
        Vec3 step;
        for (int i = 0; i < 3; ++i) step[i] = (slices.back().ipp[i] - slices.front().ipp[i]) / static_cast<double>(n - 1);
        spacingK = norm(step);
        for (std::size_t k = 0; k < n; ++k) {
            Vec3 off;
            for (int i = 0; i < 3; ++i) off[i] = slices[k].ipp[i] - (slices.front().ipp[i] + static_cast<double>(k) * step[i]);
            if (norm(off) > 0.01 * spacingK + 1e-4)
                throw RawInputError(slices[k].path, "ImagePositionPatient is off the line through the other slices by " +
                                                        std::to_string(norm(off)) + " mm");
        }
        for (int i = 0; i < 3; ++i) axisK[i] = step[i] / spacingK;
    } else {
        spacingK = f.spacingBetween > 0 ? f.spacingBetween : (f.thickness > 0 ? f.thickness : 1.0);
    }

    bool perSliceRescale = false;
    for (const auto& s : slices) perSliceRescale = perSliceRescale || s.slope != f.slope || s.intercept != f.intercept;

    // Uncompressed slices must hold their pixels: a file shorter than them is truncated (found here,
    // before any conversion starts, rather than after hours of a large series).
    for (const auto& s : slices) {
        if (DcmXfer(s.xfer).isEncapsulated() || s.xfer == EXS_DeflatedLittleEndianExplicit) continue;
        const uint64_t need = uint64_t(s.rows) * s.cols * (s.bitsAllocated / 8);
        const uint64_t size = fileSize(s.path);
        if (size < need)
            throw RawInputError(s.path, "truncated: " + sizeText(s) + " of " + std::to_string(s.bitsAllocated) +
                                            " bits needs " + std::to_string(need) + " bytes of pixel data, the file has " +
                                            std::to_string(size) + " bytes in all");
    }

    const DicomSlice first = slices.front();
    auto src = std::make_unique<DicomSeries>(folder, std::move(slices), perSliceRescale);
    RawVolumeInfo& info = src->info();
    info.format = VolumeFormat::Dicom;
    info.headerFile = folder;
    info.dataFile = first.path;
    info.dims = {{first.cols, first.rows, n}};
    info.type = perSliceRescale ? ScalarType::F32 : storedType(first);
    info.byteOrder = hostByteOrder();
    info.spacing = {{first.hasSpacing ? first.pixelSpacing[1] : 1.0, first.hasSpacing ? first.pixelSpacing[0] : 1.0, spacingK}};
    for (int r = 0; r < 3; ++r) {
        info.direction[r][0] = row[r];
        info.direction[r][1] = col[r];
        info.direction[r][2] = axisK[r];
        info.origin[r] = first.ipp[r];
    }
    if (!perSliceRescale) {
        info.scale = first.slope;
        info.intercept = first.intercept;
    }
    if (!first.hasSpacing) info.spacing = {{0, 0, spacingK}};  // resolved by --spacing or refused by the caller
    validateDims(folder, info.dims, info.type);
    return src;
}

} // namespace vdb_isosimp

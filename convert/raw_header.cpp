#include "raw_header.h"

#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <sstream>
#include <sys/stat.h>
#include <unistd.h>
#include <vector>

namespace vdb_isosimp {

// ---------------------------------------------------------------------------------------------
// Small helpers

namespace {

std::string lower(std::string s)
{
    for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

std::string trim(const std::string& s)
{
    const char* ws = " \t\r\n\f\v";
    const auto b = s.find_first_not_of(ws);
    if (b == std::string::npos) return {};
    const auto e = s.find_last_not_of(ws);
    return s.substr(b, e - b + 1);
}

bool endsWith(const std::string& s, const std::string& suffix)
{
    return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::vector<std::string> splitWs(const std::string& s)
{
    std::vector<std::string> out;
    std::istringstream in(s);
    std::string tok;
    while (in >> tok) out.push_back(tok);
    return out;
}

std::string dirOf(const std::string& path)
{
    const auto slash = path.find_last_of('/');
    if (slash == std::string::npos) return {};
    return path.substr(0, slash + 1);
}

std::string resolveRelative(const std::string& headerPath, const std::string& file)
{
    if (!file.empty() && file[0] == '/') return file;
    return dirOf(headerPath) + file;
}

std::string sysError() { return std::strerror(errno); }

uint64_t fileSize(const std::string& path)
{
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) throw RawInputError(path, "cannot open: " + sysError());
    if (S_ISDIR(st.st_mode)) throw RawInputError(path, "cannot read: is a directory");
    // Devices and FIFOs have no size to check against and may never end (/dev/zero, /dev/stdin).
    if (!S_ISREG(st.st_mode)) throw RawInputError(path, "cannot read: not a regular file");
    return static_cast<uint64_t>(st.st_size);
}

bool parseInt64(const std::string& s, int64_t& out)
{
    const std::string t = trim(s);
    if (t.empty()) return false;
    errno = 0;
    char* end = nullptr;
    const long long v = std::strtoll(t.c_str(), &end, 10);
    if (errno != 0 || *end != '\0') return false;
    out = v;
    return true;
}

/// Positive size; "overflow" set when the digits are fine but the number does not fit.
bool parseSize(const std::string& s, uint64_t& out, bool& overflow)
{
    const std::string t = trim(s);
    overflow = false;
    if (t.empty() || t[0] == '-' || t[0] == '+') return false;
    for (char c : t)
        if (c < '0' || c > '9') return false;
    errno = 0;
    char* end = nullptr;
    const unsigned long long v = std::strtoull(t.c_str(), &end, 10);
    if (errno == ERANGE) {
        overflow = true;
        return false;
    }
    out = v;
    return true;
}

bool parseDouble(const std::string& s, double& out)
{
    const std::string t = trim(s);
    if (t.empty()) return false;
    errno = 0;
    char* end = nullptr;
    const double v = std::strtod(t.c_str(), &end);
    if (*end != '\0') return false;
    out = v;
    return true;
}

std::string dimsString(const std::array<uint64_t, 3>& d)
{
    return std::to_string(d[0]) + "x" + std::to_string(d[1]) + "x" + std::to_string(d[2]);
}

// Where the data starts when a header says it fills the data file's end (NRRD `byte skip: -1`,
// MetaImage `HeaderSize = -1`): the file must hold all of it after the header's `base` bytes.
uint64_t offsetOfTrailingData(const RawVolumeInfo& info, uint64_t base)
{
    const uint64_t size = fileSize(info.dataFile);
    if (size < base + info.dataBytes())
        throw RawInputError(info.dataFile, "truncated: " + dimsString(info.dims) + " " + scalarName(info.type) + " needs " +
                                           std::to_string(info.dataBytes()) + " bytes of data, the file has " +
                                           std::to_string(size - std::min(size, base)));
    return size - info.dataBytes();
}

bool isTrue(const std::string& v)
{
    const std::string l = lower(trim(v));
    return l == "true" || l == "1" || l == "yes";
}

/// Reads the first `maxBytes` bytes of a file (fewer when it is shorter).
std::string readPrefix(const std::string& path, std::size_t maxBytes)
{
    FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) throw RawInputError(path, "cannot open: " + sysError());
    std::string buf(maxBytes, '\0');
    const std::size_t got = std::fread(&buf[0], 1, maxBytes, f);
    const bool err = std::ferror(f);
    std::fclose(f);
    if (err) throw RawInputError(path, "read error");
    buf.resize(got);
    return buf;
}

/// Offset just past `lines` newlines counted from `offset` in a file.
uint64_t skipLines(const std::string& path, uint64_t offset, int64_t lines)
{
    if (lines <= 0) return offset;
    fileSize(path);  // a regular file: the scan ends at its end
    FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) throw RawInputError(path, "cannot open: " + sysError());
    if (fseeko(f, static_cast<off_t>(offset), SEEK_SET) != 0) {
        std::fclose(f);
        throw RawInputError(path, "cannot seek to the data");
    }
    uint64_t pos = offset;
    int64_t seen = 0;
    int c;
    while (seen < lines && (c = std::fgetc(f)) != EOF) {
        ++pos;
        if (c == '\n') ++seen;
    }
    std::fclose(f);
    if (seen < lines) throw RawInputError(path, "truncated: ends within the " + std::to_string(lines) + " lines to skip");
    return pos;
}

/// Splits a NRRD vector list "(1,0,0) (0,1,0) none" into its items.
std::vector<std::string> nrrdVectorItems(const std::string& v)
{
    std::vector<std::string> items;
    std::size_t i = 0;
    while (i < v.size()) {
        while (i < v.size() && std::isspace(static_cast<unsigned char>(v[i]))) ++i;
        if (i >= v.size()) break;
        if (v[i] == '(') {
            const auto close = v.find(')', i);
            if (close == std::string::npos) return {};
            items.push_back(v.substr(i, close - i + 1));
            i = close + 1;
        } else {
            std::size_t j = i;
            while (j < v.size() && !std::isspace(static_cast<unsigned char>(v[j]))) ++j;
            items.push_back(v.substr(i, j - i));
            i = j;
        }
    }
    return items;
}

/// "(a,b,c)" -> up to 3 numbers (missing ones 0). False when malformed.
bool parseNrrdVector(const std::string& item, std::array<double, 3>& out)
{
    if (item.size() < 2 || item.front() != '(' || item.back() != ')') return false;
    std::string inner = item.substr(1, item.size() - 2);
    std::vector<double> vals;
    std::stringstream ss(inner);
    std::string part;
    while (std::getline(ss, part, ',')) {
        double d;
        if (!parseDouble(part, d)) return false;
        vals.push_back(d);
    }
    if (vals.empty() || vals.size() > 3) return false;
    out = {{0, 0, 0}};
    for (std::size_t i = 0; i < vals.size(); ++i) out[i] = vals[i];
    return true;
}

void setAxesFromColumns(RawVolumeInfo& info, const std::array<std::array<double, 3>, 3>& cols,
                        const std::string& file, const char* what)
{
    // cols[c] = world vector of one step along axis c
    for (int c = 0; c < 3; ++c) {
        const double n = std::sqrt(cols[c][0] * cols[c][0] + cols[c][1] * cols[c][1] + cols[c][2] * cols[c][2]);
        if (!(n > 0) || !std::isfinite(n))
            throw RawInputError(file, std::string("invalid ") + what + ": axis " + std::to_string(c) + " has zero length");
        info.spacing[c] = n;
        for (int r = 0; r < 3; ++r) info.direction[r][c] = cols[c][r] / n;
    }
}

// ---------------------------------------------------------------------------------------------
// NRRD

RawVolumeInfo readNrrd(const std::string& path)
{
    RawVolumeInfo info;
    info.format = VolumeFormat::Nrrd;
    info.headerFile = path;
    const std::string text = readPrefix(path, 1 << 20);
    if (text.compare(0, 7, "NRRD000") != 0) throw RawInputError(path, "not a NRRD file (no NRRD000x magic on the first line)");

    std::size_t pos = 0;
    bool first = true;
    bool ended = false;
    uint64_t headerEnd = 0;
    int dimension = -1;
    std::vector<std::string> sizes, spacings, directions;
    std::string origin, typeName, endian, encoding = "raw", dataFile;
    int64_t byteSkip = 0, lineSkip = 0;
    while (pos < text.size()) {
        auto nl = text.find('\n', pos);
        if (nl == std::string::npos) {
            if (text.size() == (1u << 20)) throw RawInputError(path, "NRRD header longer than 1 MiB or without end");
            nl = text.size();
        }
        std::string line = text.substr(pos, nl - pos);
        pos = nl + 1;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (first) { first = false; continue; }
        if (line.empty()) { ended = true; headerEnd = std::min<uint64_t>(pos, text.size()); break; }
        if (line[0] == '#') continue;
        if (line.find(":=") != std::string::npos && line.find(": ") > line.find(":=")) continue; // key/value pair
        const auto colon = line.find(": ");
        if (colon == std::string::npos) throw RawInputError(path, "malformed NRRD header line '" + line + "'");
        const std::string key = lower(trim(line.substr(0, colon)));
        const std::string value = trim(line.substr(colon + 2));
        if (key == "type") typeName = value;
        else if (key == "dimension") {
            int64_t d;
            if (!parseInt64(value, d) || d < 1) throw RawInputError(path, "invalid NRRD dimension '" + value + "'");
            if (d > 3) throw RawInputError(path, "unsupported NRRD dimension " + value + " (3-D scalar volumes only)");
            dimension = static_cast<int>(d);
        } else if (key == "sizes") sizes = splitWs(value);
        else if (key == "endian") endian = lower(value);
        else if (key == "encoding") encoding = lower(value);
        else if (key == "data file" || key == "datafile") dataFile = value;
        else if (key == "space directions") directions = nrrdVectorItems(value);
        else if (key == "spacings") spacings = splitWs(value);
        else if (key == "space origin") origin = value;
        else if (key == "byte skip") {
            if (!parseInt64(value, byteSkip) || byteSkip < -1) throw RawInputError(path, "invalid NRRD byte skip '" + value + "'");
        } else if (key == "line skip") {
            if (!parseInt64(value, lineSkip) || lineSkip < 0) throw RawInputError(path, "invalid NRRD line skip '" + value + "'");
        }
        // everything else (kinds, centers, space, content, units, ...) does not change the voxels
    }
    if (dimension < 0) throw RawInputError(path, "NRRD header lacks 'dimension'");
    if (typeName.empty()) throw RawInputError(path, "NRRD header lacks 'type'");
    if (sizes.size() != static_cast<std::size_t>(dimension))
        throw RawInputError(path, "NRRD 'sizes' has " + std::to_string(sizes.size()) + " entries for dimension " + std::to_string(dimension));
    const auto type = parseScalarType(typeName);
    if (!type) throw RawInputError(path, "unsupported type '" + typeName + "' (supported: u8 i8 u16 i16 u32 i32 f32 f64)");
    info.type = *type;
    info.dims = {{1, 1, 1}};
    for (int i = 0; i < dimension; ++i) {
        bool overflow = false;
        if (!parseSize(sizes[i], info.dims[i], overflow)) {
            if (overflow) throw RawInputError(path, "dims overflow: size '" + sizes[i] + "' does not fit in 64 bits");
            throw RawInputError(path, "invalid NRRD size '" + sizes[i] + "'");
        }
    }
    validateDims(path, info.dims, info.type);
    if (endian == "big") info.byteOrder = ByteOrder::Big;
    else if (endian.empty() || endian == "little") info.byteOrder = ByteOrder::Little;
    else throw RawInputError(path, "invalid NRRD endian '" + endian + "'");
    if (encoding == "raw") info.encoding = Encoding::Raw;
    else if (encoding == "gzip" || encoding == "gz") info.encoding = Encoding::Gzip;
    else throw RawInputError(path, "unsupported NRRD encoding '" + encoding + "' (raw and gzip are supported)");

    if (!directions.empty()) {
        if (directions.size() != static_cast<std::size_t>(dimension))
            throw RawInputError(path, "NRRD 'space directions' has " + std::to_string(directions.size()) + " entries for dimension " + std::to_string(dimension));
        std::array<std::array<double, 3>, 3> cols{{{{1, 0, 0}}, {{0, 1, 0}}, {{0, 0, 1}}}};
        for (int i = 0; i < dimension; ++i)
            if (!parseNrrdVector(directions[i], cols[i]))
                throw RawInputError(path, "invalid NRRD space direction '" + directions[i] + "'");
        setAxesFromColumns(info, cols, path, "space directions");
    } else if (!spacings.empty()) {
        if (spacings.size() != static_cast<std::size_t>(dimension))
            throw RawInputError(path, "NRRD 'spacings' has " + std::to_string(spacings.size()) + " entries for dimension " + std::to_string(dimension));
        for (int i = 0; i < dimension; ++i) {
            double s;
            if (lower(spacings[i]) == "nan") continue;
            if (!parseDouble(spacings[i], s)) throw RawInputError(path, "invalid NRRD spacing '" + spacings[i] + "'");
            info.spacing[i] = std::fabs(s);
            if (s < 0) info.direction[i][i] = -1;
        }
    }
    if (!origin.empty()) {
        if (!parseNrrdVector(origin, info.origin)) throw RawInputError(path, "invalid NRRD space origin '" + origin + "'");
    }

    uint64_t base = 0;
    if (!dataFile.empty()) {
        if (lower(dataFile.substr(0, 4)) == "list" || splitWs(dataFile).size() > 1 || dataFile.find('%') != std::string::npos)
            throw RawInputError(path, "unsupported NRRD data file list '" + dataFile + "' (one data file only)");
        info.dataFile = resolveRelative(path, dataFile);
    } else {
        if (!ended) throw RawInputError(path, "NRRD header has neither an end (blank line) nor a 'data file'");
        info.dataFile = path;
        base = headerEnd;
    }
    base = skipLines(info.dataFile, base, lineSkip);
    if (info.encoding == Encoding::Raw) {
        if (byteSkip == -1) {
            info.fileOffset = offsetOfTrailingData(info, base);
        } else {
            info.fileOffset = base + static_cast<uint64_t>(byteSkip);
        }
    } else {
        if (byteSkip == -1) throw RawInputError(path, "NRRD 'byte skip: -1' needs raw encoding");
        info.fileOffset = base;
        info.decodedSkip = static_cast<uint64_t>(byteSkip);
    }
    return info;
}

// ---------------------------------------------------------------------------------------------
// MetaImage

std::optional<ScalarType> metaType(const std::string& name)
{
    const std::string n = lower(trim(name));
    if (n == "met_uchar") return ScalarType::U8;
    if (n == "met_char") return ScalarType::I8;
    if (n == "met_ushort") return ScalarType::U16;
    if (n == "met_short") return ScalarType::I16;
    if (n == "met_uint" || n == "met_ulong") return ScalarType::U32;  // MetaIO's MET_(U)LONG is 4 bytes
    if (n == "met_int" || n == "met_long") return ScalarType::I32;
    if (n == "met_float") return ScalarType::F32;
    if (n == "met_double") return ScalarType::F64;
    return std::nullopt;
}

std::vector<double> parseNumbers(const std::string& file, const std::string& key, const std::string& value)
{
    std::vector<double> out;
    for (const auto& tok : splitWs(value)) {
        double d;
        if (!parseDouble(tok, d)) throw RawInputError(file, "invalid " + key + " '" + value + "'");
        out.push_back(d);
    }
    return out;
}

RawVolumeInfo readMetaImage(const std::string& path)
{
    RawVolumeInfo info;
    info.format = VolumeFormat::MetaImage;
    info.headerFile = path;
    const std::string text = readPrefix(path, 1 << 20);
    std::size_t pos = 0;
    int ndims = -1;
    std::string dimSize, elementType, dataFile, spacing, elementSize, offset, matrix;
    std::string channels = "1", binary = "true", msb = "false", compressed = "false";
    int64_t headerSize = 0;
    bool haveDataFile = false;
    uint64_t afterHeader = 0;
    while (pos < text.size()) {
        auto nl = text.find('\n', pos);
        if (nl == std::string::npos) nl = text.size();
        std::string line = text.substr(pos, nl - pos);
        pos = std::min(nl + 1, text.size());
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (trim(line).empty() || trim(line)[0] == '#') continue;
        const auto eq = line.find('=');
        if (eq == std::string::npos) throw RawInputError(path, "malformed MetaImage header line '" + line.substr(0, 60) + "'");
        const std::string key = lower(trim(line.substr(0, eq)));
        const std::string value = trim(line.substr(eq + 1));
        if (key == "ndims") {
            int64_t d;
            if (!parseInt64(value, d) || d < 1) throw RawInputError(path, "invalid NDims '" + value + "'");
            if (d > 3) throw RawInputError(path, "unsupported NDims " + value + " (3-D scalar volumes only)");
            ndims = static_cast<int>(d);
        } else if (key == "dimsize") dimSize = value;
        else if (key == "elementtype") elementType = value;
        else if (key == "elementnumberofchannels") channels = value;
        else if (key == "elementspacing") spacing = value;
        else if (key == "elementsize") elementSize = value;
        else if (key == "offset" || key == "position" || key == "origin") offset = value;
        else if (key == "transformmatrix" || key == "rotation" || key == "orientation") matrix = value;
        else if (key == "binarydata") binary = value;
        else if (key == "binarydatabyteordermsb" || key == "elementbyteordermsb") msb = value;
        else if (key == "compresseddata") compressed = value;
        else if (key == "headersize") {
            if (!parseInt64(value, headerSize) || headerSize < -1) throw RawInputError(path, "invalid HeaderSize '" + value + "'");
        } else if (key == "elementdatafile") {
            dataFile = value;
            haveDataFile = true;
            afterHeader = pos;
            break;
        }
    }
    if (!haveDataFile) throw RawInputError(path, "not a MetaImage header (no ElementDataFile line)");
    if (ndims < 0) throw RawInputError(path, "MetaImage header lacks NDims");
    if (elementType.empty()) throw RawInputError(path, "MetaImage header lacks ElementType");
    const auto type = metaType(elementType);
    if (!type) throw RawInputError(path, "unsupported type '" + elementType + "' (MET_UCHAR, MET_CHAR, MET_USHORT, MET_SHORT, MET_UINT, MET_INT, MET_FLOAT, MET_DOUBLE are)");
    info.type = *type;
    if (trim(channels) != "1") throw RawInputError(path, "unsupported ElementNumberOfChannels " + channels + " (scalar volumes only)");
    if (!isTrue(binary)) throw RawInputError(path, "unsupported ASCII MetaImage data (BinaryData = False)");
    const auto dimTok = splitWs(dimSize);
    if (dimTok.size() != static_cast<std::size_t>(ndims))
        throw RawInputError(path, "MetaImage DimSize has " + std::to_string(dimTok.size()) + " entries for NDims " + std::to_string(ndims));
    info.dims = {{1, 1, 1}};
    for (int i = 0; i < ndims; ++i) {
        bool overflow = false;
        if (!parseSize(dimTok[i], info.dims[i], overflow)) {
            if (overflow) throw RawInputError(path, "dims overflow: size '" + dimTok[i] + "' does not fit in 64 bits");
            throw RawInputError(path, "invalid DimSize '" + dimSize + "'");
        }
    }
    validateDims(path, info.dims, info.type);
    info.byteOrder = isTrue(msb) ? ByteOrder::Big : ByteOrder::Little;
    info.encoding = isTrue(compressed) ? Encoding::Zlib : Encoding::Raw;

    const std::string& sp = !spacing.empty() ? spacing : elementSize;
    if (!sp.empty()) {
        const auto v = parseNumbers(path, "ElementSpacing", sp);
        if (v.size() != static_cast<std::size_t>(ndims)) throw RawInputError(path, "ElementSpacing needs " + std::to_string(ndims) + " values");
        for (int i = 0; i < ndims; ++i) info.spacing[i] = v[i];
    }
    if (!offset.empty()) {
        const auto v = parseNumbers(path, "Offset", offset);
        if (v.size() != static_cast<std::size_t>(ndims)) throw RawInputError(path, "Offset needs " + std::to_string(ndims) + " values");
        for (int i = 0; i < ndims; ++i) info.origin[i] = v[i];
    }
    if (!matrix.empty()) {
        const auto v = parseNumbers(path, "TransformMatrix", matrix);
        if (v.size() != static_cast<std::size_t>(ndims * ndims))
            throw RawInputError(path, "TransformMatrix needs " + std::to_string(ndims * ndims) + " values");
        // MetaIO (ITK) writes the direction of axis c as values c*N .. c*N+N-1.
        for (int c = 0; c < ndims; ++c)
            for (int r = 0; r < ndims; ++r) info.direction[r][c] = v[c * ndims + r];
    }

    uint64_t base = 0;
    const std::string lowerFile = lower(dataFile);
    if (lowerFile == "local") {
        info.dataFile = path;
        base = afterHeader;
    } else {
        if (lowerFile == "list" || dataFile.find('%') != std::string::npos || splitWs(dataFile).size() > 1)
            throw RawInputError(path, "unsupported ElementDataFile '" + dataFile + "' (one data file or LOCAL only)");
        info.dataFile = resolveRelative(path, dataFile);
    }
    if (headerSize == -1) {
        if (info.encoding != Encoding::Raw) throw RawInputError(path, "HeaderSize = -1 needs uncompressed data");
        info.fileOffset = offsetOfTrailingData(info, base);
    } else {
        info.fileOffset = base + static_cast<uint64_t>(headerSize);
    }
    return info;
}

// ---------------------------------------------------------------------------------------------
// NIfTI-1 (and Analyze 7.5 .hdr/.img)

struct HeaderBytes {
    const unsigned char* p;
    bool swap;
    template <typename T> T get(std::size_t off) const
    {
        T v;
        unsigned char b[sizeof(T)];
        std::memcpy(b, p + off, sizeof(T));
        if (swap) std::reverse(b, b + sizeof(T));
        std::memcpy(&v, b, sizeof(T));
        return v;
    }
};

RawVolumeInfo readNifti(const std::string& path)
{
    RawVolumeInfo info;
    info.format = VolumeFormat::Nifti;
    info.headerFile = path;
    const std::string lp = lower(path);
    const bool gz = endsWith(lp, ".gz");
    unsigned char hdr[348];
    {
        DataStream in(path, 0, gz ? Encoding::Gzip : Encoding::Raw, 348);
        try {
            in.readExact(hdr, 348);
        } catch (const RawInputError& e) {
            throw RawInputError(path, std::string("not a NIfTI-1 file or truncated header: ") + e.what());
        }
    }
    int32_t sizeofHdr;
    std::memcpy(&sizeofHdr, hdr, 4);
    bool swap = false;
    if (sizeofHdr != 348) {
        int32_t swapped = static_cast<int32_t>(__builtin_bswap32(static_cast<uint32_t>(sizeofHdr)));
        if (swapped == 348) swap = true;
        else if (sizeofHdr == 540 || swapped == 540) throw RawInputError(path, "unsupported NIfTI-2 file (NIfTI-1 only)");
        else throw RawInputError(path, "not a NIfTI-1 file (sizeof_hdr is not 348)");
    }
    const bool hostLittle = hostByteOrder() == ByteOrder::Little;
    info.byteOrder = (hostLittle != swap) ? ByteOrder::Little : ByteOrder::Big;
    HeaderBytes h{hdr, swap};
    const std::string magic(reinterpret_cast<const char*>(hdr + 344), 3);
    const bool single = magic == "n+1";
    const bool pair = magic == "ni1";
    const bool analyze = !single && !pair;

    const int16_t ndim = h.get<int16_t>(40);
    if (ndim < 1 || ndim > 7) throw RawInputError(path, "invalid NIfTI dim[0] " + std::to_string(ndim));
    info.dims = {{1, 1, 1}};
    for (int i = 1; i <= ndim; ++i) {
        const int16_t d = h.get<int16_t>(40 + 2 * i);
        if (d < 1) throw RawInputError(path, "invalid NIfTI dim[" + std::to_string(i) + "] " + std::to_string(d));
        if (i <= 3) info.dims[i - 1] = static_cast<uint64_t>(d);
        else if (d != 1) throw RawInputError(path, "unsupported " + std::to_string(ndim) + "-D NIfTI volume (dim[" + std::to_string(i) + "] = " + std::to_string(d) + "; 3-D only)");
    }
    const int16_t datatype = h.get<int16_t>(70);
    switch (datatype) {
    case 2: info.type = ScalarType::U8; break;
    case 4: info.type = ScalarType::I16; break;
    case 8: info.type = ScalarType::I32; break;
    case 16: info.type = ScalarType::F32; break;
    case 64: info.type = ScalarType::F64; break;
    case 256: info.type = ScalarType::I8; break;
    case 512: info.type = ScalarType::U16; break;
    case 768: info.type = ScalarType::U32; break;
    default: throw RawInputError(path, "unsupported NIfTI datatype " + std::to_string(datatype) + " (u8 i8 u16 i16 u32 i32 f32 f64 are)");
    }
    validateDims(path, info.dims, info.type);

    float pixdim[8];
    for (int i = 0; i < 8; ++i) pixdim[i] = h.get<float>(76 + 4 * i);
    const float voxOffset = h.get<float>(108);
    // A float in the header: NaN, negative or huge values would not convert to a byte offset.
    if (!(voxOffset >= 0.0f && voxOffset < 4.0e15f))
        throw RawInputError(path, "invalid NIfTI vox_offset " + std::to_string(voxOffset));
    if (!analyze) {
        const float slope = h.get<float>(112), inter = h.get<float>(116);
        if (slope != 0.0f && std::isfinite(slope)) {
            info.scale = slope;
            info.intercept = std::isfinite(inter) ? inter : 0.0;
        }
    }
    auto step = [&](int i) {
        const double p = std::fabs(static_cast<double>(pixdim[i]));
        return (p > 0 && std::isfinite(p)) ? p : 1.0;
    };
    const int16_t qformCode = analyze ? 0 : h.get<int16_t>(252);
    const int16_t sformCode = analyze ? 0 : h.get<int16_t>(254);
    if (sformCode > 0) {
        std::array<std::array<double, 3>, 3> cols{};
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) cols[c][r] = h.get<float>(280 + 16 * r + 4 * c);
            info.origin[r] = h.get<float>(280 + 16 * r + 12);
        }
        setAxesFromColumns(info, cols, path, "NIfTI sform");
    } else if (qformCode > 0) {
        double b = h.get<float>(256), c = h.get<float>(260), d = h.get<float>(264);
        double a2 = 1.0 - (b * b + c * c + d * d);
        double a;
        if (a2 < 1e-7) {  // 180-degree rotation: renormalise (b,c,d), a = 0 (as nifti1_io does)
            const double n = 1.0 / std::sqrt(b * b + c * c + d * d);
            b *= n; c *= n; d *= n;
            a = 0.0;
        } else {
            a = std::sqrt(a2);
        }
        const double R[3][3] = {{a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)},
                                {2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)},
                                {2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b}};
        const double qfac = pixdim[0] < 0 ? -1.0 : 1.0;
        for (int r = 0; r < 3; ++r)
            for (int col = 0; col < 3; ++col) info.direction[r][col] = R[r][col] * (col == 2 ? qfac : 1.0);
        for (int i = 0; i < 3; ++i) info.spacing[i] = step(i + 1);
        info.origin = {{h.get<float>(268), h.get<float>(272), h.get<float>(276)}};
    } else {
        for (int i = 0; i < 3; ++i) info.spacing[i] = step(i + 1);
    }

    if (single) {
        const uint64_t off = voxOffset >= 352.0f ? static_cast<uint64_t>(voxOffset) : 352u;
        info.dataFile = path;
        if (gz) {
            info.encoding = Encoding::Gzip;
            info.fileOffset = 0;
            info.decodedSkip = off;
        } else {
            info.fileOffset = off;
        }
    } else {
        // header/image pair: data in the .img beside the .hdr
        std::string stem = path;
        if (gz) stem = stem.substr(0, stem.size() - 3);
        if (!endsWith(lower(stem), ".hdr")) throw RawInputError(path, "not a NIfTI-1 file (no 'n+1' magic)");
        std::string img = stem.substr(0, stem.size() - 4) + (endsWith(stem, ".HDR") ? ".IMG" : ".img");
        if (gz) img += ".gz";
        info.dataFile = img;
        const uint64_t off = voxOffset > 0 ? static_cast<uint64_t>(voxOffset) : 0;
        if (gz) {
            info.encoding = Encoding::Gzip;
            info.decodedSkip = off;
        } else {
            info.fileOffset = off;
        }
    }
    return info;
}

// ---------------------------------------------------------------------------------------------
// Bare raw

RawVolumeInfo readRaw(const std::string& path, const RawLayout& layout)
{
    RawVolumeInfo info;
    info.format = VolumeFormat::Raw;
    info.headerFile = path;
    info.dataFile = path;
    if (!layout.dims || !layout.type)
        throw RawInputError(path, std::string("a raw file needs ") + (!layout.dims ? "--dims X,Y,Z" : "") +
                                      (!layout.dims && !layout.type ? " and " : "") + (!layout.type ? "--type" : "") +
                                      " (no header to read them from)");
    info.dims = *layout.dims;
    info.type = *layout.type;
    info.byteOrder = layout.byteOrder;
    validateDims(path, info.dims, info.type);
    info.encoding = endsWith(lower(path), ".gz") ? Encoding::Gzip : Encoding::Raw;
    if (info.encoding == Encoding::Raw) info.fileOffset = layout.skip;
    else info.decodedSkip = layout.skip;
    return info;
}

} // namespace

// ---------------------------------------------------------------------------------------------
// Public

std::size_t scalarSize(ScalarType t)
{
    switch (t) {
    case ScalarType::U8: case ScalarType::I8: return 1;
    case ScalarType::U16: case ScalarType::I16: return 2;
    case ScalarType::U32: case ScalarType::I32: case ScalarType::F32: return 4;
    case ScalarType::F64: return 8;
    }
    return 1;
}

const char* scalarName(ScalarType t)
{
    switch (t) {
    case ScalarType::U8: return "u8";
    case ScalarType::I8: return "i8";
    case ScalarType::U16: return "u16";
    case ScalarType::I16: return "i16";
    case ScalarType::U32: return "u32";
    case ScalarType::I32: return "i32";
    case ScalarType::F32: return "f32";
    case ScalarType::F64: return "f64";
    }
    return "?";
}

std::optional<ScalarType> parseScalarType(const std::string& name)
{
    // collapse runs of blanks so "unsigned  short" matches
    std::string n;
    for (const auto& tok : splitWs(lower(name))) n += (n.empty() ? "" : " ") + tok;
    static const struct { const char* name; ScalarType type; } table[] = {
        {"u8", ScalarType::U8}, {"uchar", ScalarType::U8}, {"unsigned char", ScalarType::U8}, {"uint8", ScalarType::U8}, {"uint8_t", ScalarType::U8},
        {"i8", ScalarType::I8}, {"signed char", ScalarType::I8}, {"int8", ScalarType::I8}, {"int8_t", ScalarType::I8},
        {"u16", ScalarType::U16}, {"ushort", ScalarType::U16}, {"unsigned short", ScalarType::U16}, {"unsigned short int", ScalarType::U16},
        {"uint16", ScalarType::U16}, {"uint16_t", ScalarType::U16},
        {"i16", ScalarType::I16}, {"short", ScalarType::I16}, {"short int", ScalarType::I16}, {"signed short", ScalarType::I16},
        {"signed short int", ScalarType::I16}, {"int16", ScalarType::I16}, {"int16_t", ScalarType::I16},
        {"u32", ScalarType::U32}, {"uint", ScalarType::U32}, {"unsigned int", ScalarType::U32}, {"uint32", ScalarType::U32}, {"uint32_t", ScalarType::U32},
        {"i32", ScalarType::I32}, {"int", ScalarType::I32}, {"signed int", ScalarType::I32}, {"int32", ScalarType::I32}, {"int32_t", ScalarType::I32},
        {"f32", ScalarType::F32}, {"float", ScalarType::F32}, {"float32", ScalarType::F32},
        {"f64", ScalarType::F64}, {"double", ScalarType::F64}, {"float64", ScalarType::F64},
    };
    for (const auto& e : table)
        if (n == e.name) return e.type;
    return std::nullopt;
}

const char* byteOrderName(ByteOrder b) { return b == ByteOrder::Little ? "little" : "big"; }

const char* encodingName(Encoding e)
{
    switch (e) {
    case Encoding::Raw: return "raw";
    case Encoding::Gzip: return "gzip";
    case Encoding::Zlib: return "zlib";
    }
    return "?";
}

const char* formatName(VolumeFormat f)
{
    switch (f) {
    case VolumeFormat::Raw: return "raw";
    case VolumeFormat::Nrrd: return "NRRD";
    case VolumeFormat::MetaImage: return "MetaImage";
    case VolumeFormat::Nifti: return "NIfTI-1";
    case VolumeFormat::Dicom: return "DICOM";
    case VolumeFormat::Tiff: return "TIFF";
    }
    return "?";
}

ByteOrder hostByteOrder()
{
    const uint16_t one = 1;
    unsigned char b;
    std::memcpy(&b, &one, 1);
    return b == 1 ? ByteOrder::Little : ByteOrder::Big;
}

uint64_t RawVolumeInfo::voxelCount() const { return dims[0] * dims[1] * dims[2]; }
uint64_t RawVolumeInfo::dataBytes() const { return voxelCount() * scalarSize(type); }

void validateDims(const std::string& file, const std::array<uint64_t, 3>& dims, ScalarType t)
{
    const uint64_t maxDim = (uint64_t(1) << 31) - 1;
    for (auto d : dims) {
        if (d == 0) throw RawInputError(file, "invalid dims " + dimsString(dims) + ": every size must be at least 1");
        if (d > maxDim) throw RawInputError(file, "dims overflow: " + dimsString(dims) + " (each size must be below 2^31)");
    }
    uint64_t n = 0;
    if (__builtin_mul_overflow(dims[0], dims[1], &n) || __builtin_mul_overflow(n, dims[2], &n) ||
        __builtin_mul_overflow(n, static_cast<uint64_t>(scalarSize(t)), &n))
        throw RawInputError(file, "dims overflow: " + dimsString(dims) + " " + scalarName(t) + " is more than 2^64 bytes");
}

VolumeFormat detectFormat(const std::string& path)
{
    const std::string l = lower(path);
    if (endsWith(l, ".nrrd") || endsWith(l, ".nhdr")) return VolumeFormat::Nrrd;
    if (endsWith(l, ".mhd") || endsWith(l, ".mha")) return VolumeFormat::MetaImage;
    if (endsWith(l, ".nii") || endsWith(l, ".nii.gz") || endsWith(l, ".hdr") || endsWith(l, ".hdr.gz")) return VolumeFormat::Nifti;
    return VolumeFormat::Raw;
}

RawVolumeInfo readVolumeInfo(const std::string& path, const RawLayout& layout)
{
    RawVolumeInfo info;
    switch (detectFormat(path)) {
    case VolumeFormat::Nrrd: info = readNrrd(path); break;
    case VolumeFormat::MetaImage: info = readMetaImage(path); break;
    case VolumeFormat::Nifti: info = readNifti(path); break;
    case VolumeFormat::Raw: info = readRaw(path, layout); break;
    case VolumeFormat::Dicom:
    case VolumeFormat::Tiff: throw RawInputError(path, "image stacks are read through slice_source.h");  // never detected here
    }

    for (int i = 0; i < 3; ++i) {
        if (!(info.spacing[i] > 0) || !std::isfinite(info.spacing[i]))
            throw RawInputError(path, "invalid spacing " + std::to_string(info.spacing[i]) + " on axis " + std::to_string(i));
        if (!std::isfinite(info.origin[i])) throw RawInputError(path, "invalid origin (not finite)");
        for (int j = 0; j < 3; ++j)
            if (!std::isfinite(info.direction[i][j])) throw RawInputError(path, "invalid direction matrix (not finite)");
    }
    const auto& D = info.direction;
    const double det = D[0][0] * (D[1][1] * D[2][2] - D[1][2] * D[2][1]) - D[0][1] * (D[1][0] * D[2][2] - D[1][2] * D[2][0]) +
                       D[0][2] * (D[1][0] * D[2][1] - D[1][1] * D[2][0]);
    if (std::fabs(det) < 1e-12) throw RawInputError(path, "invalid direction matrix (axes are not independent)");

    if (info.encoding == Encoding::Raw) {
        const uint64_t size = fileSize(info.dataFile);
        const uint64_t need = info.dataBytes();
        const uint64_t have = size > info.fileOffset ? size - info.fileOffset : 0;
        if (have != need) {
            std::string what = std::string(have < need ? "truncated" : "size mismatch") + ": " + dimsString(info.dims) + " " +
                               scalarName(info.type) + " needs " + std::to_string(need) + " bytes of data, the file has " +
                               std::to_string(have);
            if (info.fileOffset > 0) what += " after byte offset " + std::to_string(info.fileOffset);
            throw RawInputError(info.dataFile, what);
        }
    } else {
        fileSize(info.dataFile);  // exists and is readable-ish; the stream reports the rest
    }
    return info;
}

// ---------------------------------------------------------------------------------------------
// DataStream

namespace {
constexpr std::size_t kInputBlock = 1 << 20;
}

DataStream::DataStream(const std::string& path, uint64_t offset, Encoding encoding, uint64_t total)
    : mPath(path), mEncoding(encoding), mTotal(total)
{
    mFd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (mFd < 0) throw RawInputError(path, "cannot open: " + sysError());
    if (offset > 0 && ::lseek(mFd, static_cast<off_t>(offset), SEEK_SET) < 0) {
        const std::string err = sysError();
        ::close(mFd);
        throw RawInputError(path, "cannot seek to byte " + std::to_string(offset) + ": " + err);
    }
#ifdef POSIX_FADV_SEQUENTIAL
    ::posix_fadvise(mFd, 0, 0, POSIX_FADV_SEQUENTIAL);
#endif
    if (encoding != Encoding::Raw) {
        auto* zs = new z_stream{};
        if (inflateInit2(zs, 15 + 32) != Z_OK) {  // 15+32: zlib or gzip header, detected
            delete zs;
            ::close(mFd);
            throw RawInputError(path, "cannot initialise zlib");
        }
        mZ = zs;
        mIn.resize(kInputBlock);
    }
}

DataStream::~DataStream()
{
    if (mZ) {
        auto* zs = static_cast<z_stream*>(mZ);
        inflateEnd(zs);
        delete zs;
    }
    if (mFd >= 0) ::close(mFd);
}

std::size_t DataStream::fillInput()
{
    auto* zs = static_cast<z_stream*>(mZ);
    std::size_t got = 0;
    while (got == 0 && !mInputEof) {
        const ssize_t r = ::read(mFd, &mIn[0], mIn.size());
        if (r < 0) {
            if (errno == EINTR) continue;
            throw RawInputError(mPath, "read error: " + sysError());
        }
        if (r == 0) mInputEof = true;
        got = static_cast<std::size_t>(r);
    }
    zs->next_in = reinterpret_cast<Bytef*>(&mIn[0]);
    zs->avail_in = static_cast<uInt>(got);
    return got;
}

std::size_t DataStream::readSome(void* dst, std::size_t n)
{
    auto* out = static_cast<unsigned char*>(dst);
    std::size_t done = 0;
    if (mEncoding == Encoding::Raw) {
        while (done < n) {
            const ssize_t r = ::read(mFd, out + done, std::min<std::size_t>(n - done, std::size_t(1) << 30));
            if (r < 0) {
                if (errno == EINTR) continue;
                throw RawInputError(mPath, "read error: " + sysError());
            }
            if (r == 0) break;
            done += static_cast<std::size_t>(r);
        }
        mPos += done;
        return done;
    }
    auto* zs = static_cast<z_stream*>(mZ);
    while (done < n && !mStreamEnd) {
        if (zs->avail_in == 0) {
            if (mInputEof) break;
            if (fillInput() == 0) break;
        }
        const std::size_t want = std::min<std::size_t>(n - done, std::size_t(1) << 30);
        zs->next_out = out + done;
        zs->avail_out = static_cast<uInt>(want);
        const int ret = inflate(zs, Z_NO_FLUSH);
        done += want - zs->avail_out;
        if (ret == Z_STREAM_END) {
            // Another gzip member may follow (concatenated .gz files).
            if (zs->avail_in == 0 && !mInputEof) fillInput();
            if (zs->avail_in >= 2 && zs->next_in[0] == 0x1f && zs->next_in[1] == 0x8b) {
                inflateReset(zs);
                continue;
            }
            mStreamEnd = true;
        } else if (ret == Z_BUF_ERROR) {
            if (zs->avail_in == 0 && mInputEof) break;
        } else if (ret != Z_OK) {
            const char* msg = zs->msg ? zs->msg : "invalid data";
            throw RawInputError(mPath, std::string("corrupt ") + encodingName(mEncoding) + " data (zlib: " + msg + ") after " +
                                           std::to_string(mPos + done) + " decoded bytes");
        }
    }
    mPos += done;
    return done;
}

void DataStream::readExact(void* dst, std::size_t n)
{
    const std::size_t got = readSome(dst, n);
    if (got == n) return;
    const std::string counts = "only " + std::to_string(mPos) + " of " + std::to_string(std::max(mTotal, mPos + (n - got))) + " bytes";
    if (mEncoding == Encoding::Raw) throw RawInputError(mPath, "truncated: " + counts);
    if (mStreamEnd) throw RawInputError(mPath, std::string(encodingName(mEncoding)) + " stream ends early: " + counts);
    throw RawInputError(mPath, std::string(encodingName(mEncoding)) + " stream ends early (compressed file cut short): " + counts);
}

void DataStream::skip(uint64_t n)
{
    if (n == 0) return;
    if (mEncoding == Encoding::Raw) {
        if (::lseek(mFd, static_cast<off_t>(n), SEEK_CUR) < 0) throw RawInputError(mPath, "cannot seek: " + sysError());
        mPos += n;
        return;
    }
    std::vector<unsigned char> sink(std::min<uint64_t>(n, 1 << 16));
    while (n > 0) {
        const std::size_t k = static_cast<std::size_t>(std::min<uint64_t>(n, sink.size()));
        readExact(sink.data(), k);
        n -= k;
    }
}

} // namespace vdb_isosimp

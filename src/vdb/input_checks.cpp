#include "vdb/block_order.h"
#include "vdb/input_checks.h"

#include "core/edge_key.h"
#include "vdb_isosimp/errors.h"

#include <openvdb/math/Transform.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <sys/stat.h>
#include <unistd.h>
#include <vector>

#include <openvdb/io/Compression.h>
#include <openvdb/points/StreamCompression.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace vdb_isosimp {

// Per-leaf copy of the value-compression codes and chunk sizes that newer files carry in the grid's
// metadata ("file_delayed_load"). OpenVDB seeks over leaves with these sizes rather than the ones in
// the data, so they must agree with the data.
struct DelayedLoadSizes {
    bool present = false;
    std::vector<int8_t> codes;
    std::vector<int64_t> sizes;
};

// ---------------------------------------------------------------------------------------------
// File structure

namespace {

// Bounded little-endian reads from a file: every length read from the file is checked against the
// bytes that are left (before the limit set, else the file's end) before anything is skipped or
// allocated. Reads go through one window of the file (pread), so walking a grid's hundreds of
// thousands of small leaf records costs a sequential read, not a system call per field.
class BoundedReader {
public:
    BoundedReader(const std::string& path, uint64_t size)
        : mFd(::open(path.c_str(), O_RDONLY | O_CLOEXEC)), mSize(size), mLimit(size)
    {
    }
    ~BoundedReader()
    {
        if (mFd >= 0) ::close(mFd);
    }
    BoundedReader(const BoundedReader&) = delete;
    BoundedReader& operator=(const BoundedReader&) = delete;

    bool ok() const { return mFd >= 0; }
    uint64_t size() const { return mSize; }
    uint64_t pos() const { return mPos; }
    uint64_t left() const { return mLimit > mPos ? mLimit - mPos : 0; }
    // Reads and skips stop at `limit` (a grid's end, its topology's end) until the next call.
    void setLimit(uint64_t limit) { mLimit = std::min(limit, mSize); }

    bool bytes(void* dst, uint64_t n)
    {
        if (n > left()) return false;
        char* out = static_cast<char*>(dst);
        while (n > 0) {
            if (mPos < mWinStart || mPos >= mWinStart + mWinLen) {
                if (!fill()) return false;
            }
            const uint64_t at = mPos - mWinStart;
            const uint64_t k = std::min<uint64_t>(n, mWinLen - at);
            std::memcpy(out, mWin.data() + at, size_t(k));
            out += k;
            n -= k;
            mPos += k;
        }
        return true;
    }
    bool skip(uint64_t n)
    {
        if (n > left()) return false;
        mPos += n;
        return true;
    }
    bool seek(uint64_t p)
    {
        if (p > mLimit) return false;
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
        return (k == 0 || bytes(&(*out)[0], k)) && skip(n - k);
    }

private:
    static constexpr uint64_t kWindow = 256 << 10;

    bool fill()
    {
        if (mWin.empty()) mWin.resize(kWindow);
        // No further than the limit: a walk of a few records apart reads those, not a window past them.
        const uint64_t want = std::min<uint64_t>(kWindow, mLimit - std::min(mLimit, mPos));
        uint64_t got = 0;
        while (got < want) {
            const ssize_t r = ::pread(mFd, mWin.data() + got, size_t(want - got), off_t(mPos + got));
            if (r < 0 && errno == EINTR) continue;
            if (r <= 0) break;
            got += uint64_t(r);
        }
        mWinStart = mPos;
        mWinLen = got;
        return got > 0 && got == want;
    }

    int mFd;
    uint64_t mSize;
    uint64_t mLimit;
    uint64_t mPos = 0;
    std::vector<char> mWin;
    uint64_t mWinStart = 0, mWinLen = 0;
};

[[noreturn]] void damaged(const std::string& path, const std::string& what)
{
    throw InputError(path + ": truncated or damaged OpenVDB file (" + what + ")");
}

std::string printable(std::string s)
{
    s = s.substr(0, s.find('\x1e'));  // unique-name suffix of repeated names
    for (char& c : s)
        if (static_cast<unsigned char>(c) < 0x20) c = '?';
    return s;
}

using GridEntry = VdbGridEntry;
using FileEntries = VdbFileEntries;

void walkStreamedGrids(const std::string& path, BoundedReader& in, int32_t grids, FileEntries& out);

// A grid descriptor's names (unique name, tree type, instance parent), as every layout stores them
// before the grid's offsets.
bool readDescriptor(BoundedReader& in, GridEntry& e)
{
    if (!in.string(&e.uniqueName, 1 << 16) || !in.string(&e.type) || !in.string(&e.parent, 1 << 16)) return false;
    e.plain = e.uniqueName.substr(0, e.uniqueName.find('\x1e'));
    e.name = printable(e.plain);
    return true;
}

// Sizes of the metadata values OpenVDB reads as a fixed number of bytes whatever the stored size says
// (a stored size that disagrees would shift every read after it).
uint64_t fixedMetadataSize(const std::string& type)
{
    static const std::map<std::string, uint64_t> sizes = {
        {"bool", 1},   {"int32", 4},  {"int64", 8},  {"float", 4},  {"double", 8}, {"vec2i", 8},
        {"vec2s", 8},  {"vec2d", 16}, {"vec3i", 12}, {"vec3s", 12}, {"vec3d", 24}, {"vec4i", 16},
        {"vec4s", 16}, {"vec4d", 32}, {"mat4s", 64}, {"mat4d", 128}};
    const auto it = sizes.find(type);
    return it == sizes.end() ? 0 : it->second;
}

// c-blosc's 16-byte chunk header: format versions, flags, type size, then the uncompressed size, the
// block size and the compressed size (uint32 each); a chunk of several blocks starts them at the
// offsets that follow. c-blosc trusts all of these, so they are checked against what the file gives
// the chunk and what the reader expects before OpenVDB hands the chunk to it.
std::string checkBloscChunk(BoundedReader& in, uint64_t chunkBytes, uint64_t expectedBytes)
{
    unsigned char h[16];
    if (chunkBytes < 16 || !in.bytes(h, 16)) return "blosc chunk shorter than its header";
    uint32_t nbytes = 0, blocksize = 0, cbytes = 0;
    std::memcpy(&nbytes, h + 4, 4);
    std::memcpy(&blocksize, h + 8, 4);
    std::memcpy(&cbytes, h + 12, 4);
    if (nbytes != expectedBytes)
        return "blosc chunk decompresses to " + std::to_string(nbytes) + " bytes, " + std::to_string(expectedBytes) +
               " expected";
    if (cbytes != chunkBytes)
        return "blosc chunk states " + std::to_string(cbytes) + " compressed bytes, the file gives it " +
               std::to_string(chunkBytes);
    const bool copied = h[2] & 0x2;  // BLOSC_MEMCPYED: the data follows the header as is
    if (copied) return cbytes == uint64_t(nbytes) + 16 ? "" : "stored blosc chunk of the wrong size";
    if (nbytes == 0) return "";
    if (blocksize == 0 || blocksize > nbytes) return "blosc chunk with an invalid block size";
    const uint64_t blocks = (uint64_t(nbytes) + blocksize - 1) / blocksize;
    const uint64_t first = 16 + 4 * blocks;
    if (first > cbytes) return "blosc chunk too short for its blocks";
    for (uint64_t b = 0; b < blocks; ++b) {
        int32_t start = 0;
        if (!in.value(start)) return "blosc chunk ends early";
        if (start < 0 || uint64_t(start) < first || uint64_t(start) >= cbytes) return "blosc block offset outside its chunk";
    }
    return "";
}

// The zlib stream header (RFC 1950): deflate, a window of at most 32 KB, the check bits, no preset
// dictionary.
bool zlibHeaderFits(unsigned char cmf, unsigned char flg)
{
    return (cmf & 0x0f) == 8 && (cmf >> 4) <= 7 && ((unsigned(cmf) << 8) | flg) % 31 == 0 && !(flg & 0x20);
}

// What one node's compressed values take in the file (io::readCompressedValues): a code byte, up to
// two inactive values, a selection mask, then the values (all, or only the active ones with mask
// compression), zip- or blosc-compressed behind an int64 size (negative: stored as is) or raw.
struct ValuesRecord {
    int8_t code = 0;
    uint64_t chunkBytes = 0;  // with its 8-byte size; 0 when nothing is stored
    bool hasChunk = false;
};

// What a node's value-compression code stores between the code and the values: one or two inactive
// values (codes 2, 4 and 5), then a selection mask (codes 3, 4 and 5).
uint64_t storedBeforeChunk(int8_t code, uint64_t valueSize, uint64_t nodeValues)
{
    const uint64_t inactive = code == 2 || code == 4 ? valueSize : code == 5 ? 2 * valueSize : 0;
    return inactive + (code == 3 || code == 4 || code == 5 ? nodeValues / 8 : 0);
}

// `decompress`: also decompress the chunk (tile values of internal nodes). OpenVDB decompresses those
// while it builds the topology, and a throw there leaks the root's child it was filling (the
// root inserts a child only once it is read), besides leaving a partial tree.
std::string walkValues(BoundedReader& in, uint32_t compression, bool half, uint64_t valueSize, uint64_t nodeValues,
                       uint64_t active, ValuesRecord& rec, bool decompress = false)
{
    const bool maskCompressed = compression & openvdb::io::COMPRESS_ACTIVE_MASK;
    if (!in.value(rec.code)) return "ends early";
    if (rec.code < 0 || rec.code > 6) return "unknown value-compression code " + std::to_string(int(rec.code));
    if (!maskCompressed && rec.code != 6) return "value-compression code " + std::to_string(int(rec.code)) + " without mask compression";
    if (!in.skip(storedBeforeChunk(rec.code, valueSize, nodeValues))) return "ends early";
    const uint64_t count = maskCompressed && rec.code != 6 ? active : nodeValues;
    const uint64_t expected = count * (half ? 2 : valueSize);
    if (half && count == 0) return "";  // OpenVDB stores no half floats at all then
    if (!(compression & (openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ZIP))) {
        return in.skip(expected) ? "" : "ends early";
    }
    rec.hasChunk = true;
    int64_t n = 0;
    if (!in.value(n)) return "ends early";
    if (n <= 0) {
        const uint64_t stored = uint64_t(0) - uint64_t(n);
        if (stored != expected)
            return "uncompressed chunk of " + std::to_string(stored) + " bytes, " + std::to_string(expected) + " expected";
        rec.chunkBytes = 8 + stored;
        return in.skip(stored) ? "" : "ends early";
    }
    if (uint64_t(n) > in.left())
        return "chunk of " + std::to_string(n) + " bytes runs past the grid's data";
    rec.chunkBytes = 8 + uint64_t(n);
    const uint64_t start = in.pos();
    if (compression & openvdb::io::COMPRESS_BLOSC) {
        const std::string why = checkBloscChunk(in, uint64_t(n), expected);
        if (!why.empty()) return why;
    } else {
        unsigned char h[2];
        if (n < 8 || !in.bytes(h, 2) || !zlibHeaderFits(h[0], h[1])) return "zip chunk without a zlib header";
        // zlib never grows data by more than 5 bytes per 16 KB block plus its 6-byte frame.
        if (uint64_t(n) > expected + expected / 1000 + 64) return "zip chunk larger than its data could compress to";
    }
    if (decompress) {
        std::string chunk(size_t(8 + n), '\0');
        std::memcpy(&chunk[0], &n, 8);
        if (!in.seek(start) || !in.bytes(&chunk[8], uint64_t(n))) return "ends early";
        std::istringstream is(chunk);
        std::vector<char> values(size_t(expected) + 1);
        try {
            if (compression & openvdb::io::COMPRESS_BLOSC) openvdb::io::bloscFromStream(is, values.data(), size_t(expected));
            else openvdb::io::unzipFromStream(is, values.data(), size_t(expected));
        } catch (const std::exception&) {
            return "compressed data is damaged";
        }
    }
    return in.seek(start + uint64_t(n)) ? "" : "ends early";
}

// One of the two arrays of "file_delayed_load": uint32 stored size (0: raw), then blosc or raw bytes.
// OpenVDB pads arrays of 48 to 127 bytes to 128 before blosc compresses them.
constexpr uint64_t kBloscPadBytes = 128;

template <typename T>
std::string readDelayedArray(BoundedReader& in, uint64_t end, uint32_t count, std::vector<T>* out)
{
    uint32_t bytes = 0;
    if (!in.value(bytes)) return "ends early";
    const uint64_t want = uint64_t(count) * sizeof(T);
    if (bytes == 0) {
        if (want > end - std::min(end, in.pos())) return "array runs past the metadata";
        if (out) {
            out->resize(count);
            return want == 0 || in.bytes(out->data(), want) ? "" : "ends early";
        }
        return in.skip(want) ? "" : "ends early";
    }
    if (bytes > end - std::min(end, in.pos())) return "array runs past the metadata";
    const uint64_t start = in.pos();
    std::string why = checkBloscChunk(in, bytes, want);
    const uint64_t packedBytes = want < kBloscPadBytes && !why.empty() && in.seek(start) &&
                                         checkBloscChunk(in, bytes, kBloscPadBytes).empty()
                                     ? kBloscPadBytes
                                     : want;
    if (packedBytes != want) why.clear();
    if (!why.empty()) return why;
    if (out) {
        std::vector<char> packed(bytes);
        if (!in.seek(start) || !in.bytes(packed.data(), bytes)) return "ends early";
        // Decoded in place, with c-blosc's room for its overhead; a padded array through a small buffer.
        constexpr size_t kRoom = 16;
        try {
            if (packedBytes == want) {
                out->resize(count + (kRoom + sizeof(T) - 1) / sizeof(T));
                openvdb::compression::bloscDecompress(reinterpret_cast<char*>(out->data()), size_t(want),
                                                      out->size() * sizeof(T), packed.data());
            } else {
                char padded[kBloscPadBytes + kRoom];
                openvdb::compression::bloscDecompress(padded, size_t(packedBytes), sizeof padded, packed.data());
                out->resize(count);
                if (want) std::memcpy(out->data(), padded, size_t(want));
            }
        } catch (const std::exception&) {
            return "array does not decompress";
        }
        out->resize(count);
    }
    return in.seek(start + bytes) ? "" : "ends early";
}

// A descriptor's tree type without the suffix that marks a grid stored as half floats (`half`), as
// io::GridDescriptor reads it.
std::string treeType(const std::string& stored, bool& half)
{
    const std::string suffix = "_HalfFloat";
    half = stored.size() >= suffix.size() && stored.compare(stored.size() - suffix.size(), suffix.size(), suffix) == 0;
    return half ? stored.substr(0, stored.size() - suffix.size()) : stored;
}

// The trees this walk knows: Tree4<float or double, 5, 4, 3>, maybe stored as half floats.
bool treeFormat(const std::string& stored, bool& half, uint64_t& valueSize)
{
    const std::string type = treeType(stored, half);
    valueSize = type == "Tree_float_5_4_3" ? 4 : type == "Tree_double_5_4_3" ? 8 : 0;
    return valueSize != 0;
}

// A grid's "is_saved_as_half_float" metadata as its map holds it: OpenVDB reads the topology as half
// floats if and only if it is there and true (GridBase::saveFloatAsHalf), whatever the grid's type says.
enum class HalfFlag { Absent, No, Yes, Other };

// A metadata map (file or grid): uint32 count, then per item name, type name, uint32 size and the
// value. Every size must fit before `end`, fixed-size types must state their size, and the
// delayed-load table (read by OpenVDB with no bound of its own) must be consistent.
// `delayedSpan`, where given: where the item named "file_delayed_load" lies (left as it is without one).
std::string walkMetaMap(BoundedReader& in, uint64_t end, uint64_t maxLeaves, DelayedLoadSizes* delayed,
                        HalfFlag* half = nullptr, std::array<uint64_t, 2>* delayedSpan = nullptr)
{
    uint32_t count = 0;
    if (!in.value(count) || count > in.left() / 12) return "metadata count ends early or is invalid";
    for (uint32_t i = 0; i < count; ++i) {
        const uint64_t itemStart = in.pos();
        std::string name, type;
        uint32_t n = 0;
        if (!in.string(&name) || !in.string(&type) || !in.value(n) || n > end - std::min(end, in.pos()))
            return "metadata item " + std::to_string(i + 1) + " of " + std::to_string(count) + " ends early";
        const uint64_t valueStart = in.pos();
        const uint64_t fixed = fixedMetadataSize(type);
        if (fixed && n != fixed)
            return "metadata '" + printable(name) + "' of type " + type + " states " + std::to_string(n) + " bytes";
        if (half && name == openvdb::GridBase::META_SAVE_HALF_FLOAT) {
            unsigned char b = 0;
            *half = type != "bool" || n != 1 ? HalfFlag::Other : !in.value(b) ? HalfFlag::Other : b ? HalfFlag::Yes : HalfFlag::No;
        }
        if (type == "__delayedload" && n > 0) {
            const uint64_t valueEnd = valueStart + n;
            uint32_t leaves = 0;
            if (!in.value(leaves)) return "delayed-load metadata ends early";
            if (leaves > maxLeaves) return "delayed-load metadata lists more leaves than the grid's data holds";
            std::string why = readDelayedArray(in, valueEnd, leaves, delayed ? &delayed->codes : nullptr);
            uint32_t sizesBytes = 0;
            if (why.empty() && !in.value(sizesBytes)) why = "ends early";
            if (why.empty() && sizesBytes != std::numeric_limits<uint32_t>::max()) {
                in.seek(in.pos() - 4);
                why = readDelayedArray(in, valueEnd, leaves, delayed ? &delayed->sizes : nullptr);
            }
            if (why.empty() && in.pos() > valueEnd) why = "runs past its stated size";
            if (!why.empty()) {
                if (delayed) *delayed = DelayedLoadSizes();
                return "delayed-load metadata: " + why;
            }
            if (delayed) delayed->present = true;
        }
        if (!in.seek(valueStart + n)) return "metadata '" + printable(name) + "' ends early";
        if (delayedSpan && name == openvdb::GridBase::META_FILE_DELAYED_LOAD) *delayedSpan = {itemStart, valueStart + n};
    }
    return "";
}

// Bytes of the linear maps' own data (math/Maps.h read()); 0 for other map types.
uint64_t linearMapBytes(const std::string& type)
{
    if (type == "AffineMap" || type == "UnitaryMap") return 128;
    if (type == "ScaleMap" || type == "UniformScaleMap") return 120;
    if (type == "ScaleTranslateMap" || type == "UniformScaleTranslateMap") return 144;
    if (type == "TranslationMap") return 24;
    return 0;
}

FileEntries readFileEntries(const std::string& path)
{
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0)
        throw InputError(path + ": cannot open file for reading (" + std::strerror(errno) + ")");
    if (S_ISDIR(st.st_mode)) throw InputError(path + ": is a directory, not a .vdb file");
    FileEntries out;
    if (!S_ISREG(st.st_mode)) return out;  // pipes and devices cannot be checked without consuming them
    const uint64_t size = uint64_t(st.st_size);
    BoundedReader in(path, size);
    if (!in.ok()) throw InputError(path + ": cannot open file for reading (" + std::strerror(errno) + ")");

    int64_t magic = 0;
    if (!in.value(magic) || int32_t(magic) != openvdb::OPENVDB_MAGIC)
        throw InputError(path + ": not a readable OpenVDB file (no VDB magic number)");
    uint32_t major = 0, minor = 0;
    char hasOffsets = 0;
    if (!in.value(out.version)) damaged(path, "header ends early");
    // Older layouts differ in their header and their trees; OpenVDB would read them unchecked.
    if (out.version < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION)
        throw InputError(path + ": OpenVDB file format " + std::to_string(out.version) + " is older than format " +
                         std::to_string(openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) +
                         ", the oldest this tool reads; save the file again with a current OpenVDB");
    if (!in.value(major) || !in.value(minor) || !in.value(hasOffsets) || !in.skip(36))  // 36: UUID text
        damaged(path, "header ends early");

    const std::string fileMeta = walkMetaMap(in, size, 0, nullptr);
    if (!fileMeta.empty()) damaged(path, "file " + fileMeta);

    int32_t grids = 0;
    if (!in.value(grids) || grids < 0 || uint64_t(grids) > in.left() / 36) damaged(path, "grid count ends early or is invalid");
    if (!hasOffsets) {
        walkStreamedGrids(path, in, grids, out);
        out.checkable = true;
        return out;
    }
    for (int32_t g = 0; g < grids; ++g) {
        GridEntry e;
        int64_t gridPos = 0, blockPos = 0, endPos = 0;
        if (!readDescriptor(in, e) || !in.value(gridPos) || !in.value(blockPos) || !in.value(endPos))
            damaged(path, "descriptor of grid " + std::to_string(g + 1) + " of " + std::to_string(grids) + " ends early");
        const uint64_t here = in.pos();
        const bool ordered = gridPos >= 0 && uint64_t(gridPos) >= here && endPos >= gridPos &&
                             (blockPos == 0 || (blockPos >= gridPos && blockPos <= endPos));
        if (!ordered) damaged(path, "grid '" + e.name + "' has inconsistent offsets");
        if (uint64_t(endPos) > size)
            damaged(path, "grid '" + e.name + "' ends at byte " + std::to_string(endPos) + " but the file has " +
                              std::to_string(size) + " bytes");
        if (!in.seek(uint64_t(endPos))) damaged(path, "cannot seek to the end of grid '" + e.name + "'");
        e.gridPos = uint64_t(gridPos);
        e.blockPos = uint64_t(blockPos);
        e.endPos = uint64_t(endPos);
        out.grids.push_back(std::move(e));
    }
    out.checkable = true;
    return out;
}

// Walks a grid's compression flags, metadata and transform (what OpenVDB reads for every grid when
// it lists them) and leaves `in` at the topology. Returns false when the transform is not a linear map
// (OpenVDB reads those itself; they are refused before any topology is read).
bool walkGridHeader(const std::string& path, BoundedReader& in, const GridEntry& e, uint32_t& compression,
                    DelayedLoadSizes* delayed, GridEntry* spans = nullptr)
{
    const uint64_t headerEnd = e.blockPos ? e.blockPos : e.endPos;
    in.setLimit(headerEnd);
    if (!in.seek(e.gridPos) || !in.value(compression)) damaged(path, "grid '" + e.name + "' ends early");
    if (compression & ~uint32_t(0x7)) damaged(path, "grid '" + e.name + "' has unknown compression flags");
    // A leaf record takes at least its value mask and code byte.
    const uint64_t maxLeaves = e.blockPos || e.streamed ? (e.endPos - std::max(e.blockPos, e.gridPos)) / 65 : 0;
    HalfFlag halfMeta = HalfFlag::Absent;
    const uint64_t metaPos = in.pos();
    std::array<uint64_t, 2> delayedSpan{0, 0};
    const std::string meta = walkMetaMap(in, headerEnd, maxLeaves, delayed, &halfMeta, &delayedSpan);
    if (!meta.empty()) damaged(path, "grid '" + e.name + "': " + meta);
    // The topology walk follows the type's "_HalfFloat"; OpenVDB follows the metadata. A file where they
    // differ would be read one way here and another there (and OpenVDB leaks the node it was filling
    // when that read fails).
    bool half = false;
    uint64_t valueSize = 0;
    if (treeFormat(e.type, half, valueSize) && (halfMeta == HalfFlag::Other || (halfMeta == HalfFlag::Yes) != half))
        damaged(path, "grid '" + e.name + "': its metadata '" + openvdb::GridBase::META_SAVE_HALF_FLOAT +
                          "' disagrees with its type " + printable(e.type));
    std::string mapType;
    if (!in.string(&mapType, 64)) damaged(path, "grid '" + e.name + "': transform ends early");
    const uint64_t mapBytes = linearMapBytes(mapType);
    if (!mapBytes) return false;
    if (!in.skip(mapBytes)) damaged(path, "grid '" + e.name + "': transform ends early");
    if (spans) {
        spans->metaPos = metaPos;
        spans->delayedBegin = delayedSpan[0];
        spans->delayedEnd = delayedSpan[1];
        spans->headerEnd = in.pos();
    }
    return true;
}

} // namespace

struct LeafRecords {
    std::string path, grid;
    uint64_t fileSize = 0;
    uint32_t compression = 0;
    bool half = false;
    uint64_t valueSize = 0;
    DelayedLoadSizes delayed;    // the codes only
    std::vector<uint64_t> at;    // where each record starts, then where they end
    VdbGridLayout layout;        // the leaves' active counts
    uint64_t order = 0;          // the leaves' origins in file order, hashed (addToLeafOrder)
    size_t first = 0, last = 0;  // the records this process walked
};

namespace {

// One word into a hash (multiply and fold): the stored tree's digest and the leaves' order.
void mixInto(uint64_t& h, uint64_t w)
{
    h = (h ^ w) * 0x9E3779B97F4A7C15ull;
    h ^= h >> 29;
}

void addToLeafOrder(uint64_t& h, const std::array<int32_t, 3>& o)
{
    mixInto(h, uint64_t(uint32_t(o[0])) << 32 | uint32_t(o[1]));
    mixInto(h, uint64_t(uint32_t(o[2])));
}

} // namespace

VdbFileEntries checkVdbFileStructure(const std::string& path)
{
    FileEntries f = readFileEntries(path);
    if (!f.checkable) return f;
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) return f;
    BoundedReader in(path, uint64_t(st.st_size));
    // Decoded too (OpenVDB decodes them when it lists the grids), and kept for checkVdbGridData up to
    // kKeptDelayedBytes in all: a file of many large grids keeps the first ones only, and the grid's
    // walk decodes the others again.
    constexpr uint64_t kKeptDelayedBytes = uint64_t(64) << 20;
    uint64_t kept = 0;
    for (GridEntry& e : f.grids) {
        uint32_t compression = 0;
        auto delayed = std::make_shared<DelayedLoadSizes>();
        walkGridHeader(path, in, e, compression, delayed.get(), e.streamed ? nullptr : &e);
        const uint64_t bytes = delayed->codes.size() + delayed->sizes.size() * sizeof(int64_t);
        if (delayed->present && kept + bytes <= kKeptDelayedBytes) {
            kept += bytes;
            e.delayed = std::move(delayed);
        }
    }
    return f;
}

openvdb::GridPtrVecPtr readGridHeaders(const std::string& path, const VdbFileEntries& entries, const openvdb::io::File& file)
{
    if (!entries.checkable || entries.grids.empty()) return nullptr;
    uint64_t end = 0;
    for (const GridEntry& e : entries.grids) {
        bool half = false;
        if (e.headerEnd == 0 || !openvdb::GridBase::isRegistered(treeType(e.type, half))) return nullptr;
        end = std::max(end, e.headerEnd);
    }
    BoundedReader in(path, end);
    std::vector<std::pair<std::string, openvdb::GridBase::Ptr>> grids;
    for (const GridEntry& e : entries.grids) {
        bool half = false;
        const std::string type = treeType(e.type, half);
        // The map's bytes around the delayed-load item, its count one less; then the transform.
        const bool table = e.delayedEnd > e.delayedBegin;
        const uint64_t head = (table ? e.delayedBegin : e.headerEnd) - e.metaPos, tail = table ? e.headerEnd - e.delayedEnd : 0;
        std::string bytes(head + tail, '\0');
        if (!in.seek(e.metaPos) || !in.bytes(bytes.data(), head) ||
            (tail && (!in.seek(e.delayedEnd) || !in.bytes(bytes.data() + head, tail))))
            return nullptr;
        if (table) {
            uint32_t count = 0;
            std::memcpy(&count, bytes.data(), sizeof count);
            --count;
            std::memcpy(bytes.data(), &count, sizeof count);
        }
        std::istringstream is(bytes);
        openvdb::io::setVersion(is, file.libraryVersion(), file.fileVersion());
        openvdb::GridBase::Ptr grid = openvdb::GridBase::createGrid(type);
        grid->setSaveFloatAsHalf(half);
        grid->readMeta(is);
        grid->readTransform(is);
        grids.emplace_back(e.plain, std::move(grid));
    }
    // io::File lists its descriptors from a map by name (equal names in the file's order).
    std::stable_sort(grids.begin(), grids.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    auto out = std::make_shared<openvdb::GridPtrVec>();
    for (auto& g : grids) out->push_back(std::move(g.second));
    return out;
}

namespace {

// Tree4<float or double, 5, 4, 3>: the node sizes the topology walk follows.
constexpr int kLog2Upper = 5, kLog2Lower = 4;
constexpr uint64_t kLeafValues = 512;

uint64_t popcount(const std::vector<uint64_t>& words)
{
    uint64_t n = 0;
    for (uint64_t w : words) n += uint64_t(__builtin_popcountll(w));
    return n;
}

std::string coordText(const std::array<int32_t, 3>& c)
{
    return "[" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " + std::to_string(c[2]) + "]";
}

// A leaf's record that the walk found unsound: the same line wherever the walk finds it.
InputError damagedLeaf(const std::string& path, const std::string& grid, const std::array<int32_t, 3>& origin,
                       const std::string& why)
{
    return InputError(path + ": grid '" + grid + "', leaf " + coordText(origin) + ": compressed data is damaged (" + why + ")");
}

struct TopologyWalk {
    const std::string& path;
    const std::string& grid;
    BoundedReader& in;
    uint32_t compression;
    bool half;
    uint64_t valueSize;
    VdbGridLayout& out;

    [[noreturn]] void fail(const std::string& what) const { damaged(path, "grid '" + grid + "': topology " + what); }

    // An internal node (child mask, value mask, tile values, then its children in mask order).
    void internal(int log2, const std::array<int32_t, 3>& origin)
    {
        const uint64_t values = uint64_t(1) << (3 * log2);
        std::vector<uint64_t> childMask(values / 64), valueMask(values / 64);
        if (!in.bytes(childMask.data(), values / 8) || !in.bytes(valueMask.data(), values / 8)) fail("ends early");
        ValuesRecord rec;
        const std::string why = walkValues(in, compression, half, valueSize, values, popcount(valueMask), rec, true);
        if (!why.empty()) fail("node " + coordText(origin) + ": tile values: " + why);
        const int childTotal = log2 == kLog2Upper ? kLog2Lower + 3 : 3;
        const int32_t dim = int32_t(1) << log2;
        for (uint64_t w = 0; w < childMask.size(); ++w)
            for (uint64_t bits = childMask[w]; bits; bits &= bits - 1) {
                const uint64_t i = w * 64 + uint64_t(__builtin_ctzll(bits));
                // Wrapping like OpenVDB's own coordinates: a stored origin may lie anywhere.
                const auto at = [&](int a, uint64_t local) { return int32_t(uint32_t(origin[a]) + uint32_t(local << childTotal)); };
                const std::array<int32_t, 3> c = {at(0, i >> (2 * log2)), at(1, (i >> log2) & uint64_t(dim - 1)),
                                                  at(2, i & uint64_t(dim - 1))};
                if (log2 == kLog2Upper) {
                    const uint64_t start = in.pos();
                    internal(kLog2Lower, c);
                    out.lowerNodes.push_back({start, in.pos()});
                } else {
                    uint64_t mask[8];
                    if (!in.bytes(mask, sizeof mask)) fail("ends early");
                    uint16_t active = 0;
                    for (uint64_t m : mask) active = uint16_t(active + __builtin_popcountll(m));
                    out.leafOrigins.push_back(c);
                    out.leafActive.push_back(active);
                }
            }
    }

    // Tree header and root node: buffer count, background, tiles, then the upper internal nodes.
    void root()
    {
        int32_t buffers = 0;
        uint32_t tiles = 0, children = 0;
        if (!in.value(buffers) || buffers != 1 || !in.skip(valueSize) || !in.value(tiles) || !in.value(children))
            fail("header ends early or is invalid");
        const uint64_t tileBytes = 12 + valueSize + 1, childBytes = 12 + 2 * 4096 + 1;
        if (tiles > in.left() / tileBytes || children > in.left() / childBytes)
            fail("root states " + std::to_string(tiles) + " tiles and " + std::to_string(children) +
                 " children, more than its bytes hold");
        constexpr int32_t kAlign = (int32_t(1) << (kLog2Upper + kLog2Lower + 3)) - 1;
        std::array<int32_t, 3> prev{};
        for (uint32_t t = 0; t < tiles; ++t) {
            std::array<int32_t, 3> c{};
            unsigned char active = 0;
            if (!in.bytes(c.data(), 12) || !in.skip(valueSize) || !in.value(active)) fail("ends early");
            if (((c[0] | c[1] | c[2]) & kAlign) || active > 1 || (t > 0 && !(prev < c)))
                fail("root tile " + coordText(c) + " is misplaced");
            prev = c;
        }
        for (uint32_t n = 0; n < children; ++n) {
            std::array<int32_t, 3> c{};
            if (!in.bytes(c.data(), 12)) fail("ends early");
            if (((c[0] | c[1] | c[2]) & kAlign) || (n > 0 && !(prev < c))) fail("root child " + coordText(c) + " is misplaced");
            prev = c;
            internal(kLog2Upper, c);
        }
    }
};

// One leaf's record at `in`'s position (value mask, then the voxel values: walkValues) against the
// topology's active count and the delayed-load metadata: empty when it is sound, else what is wrong.
std::string walkLeaf(BoundedReader& in, size_t i, const VdbGridLayout& layout, uint32_t compression, bool half,
                     uint64_t valueSize, const DelayedLoadSizes& delayed)
{
    uint64_t mask[8];
    if (!in.bytes(mask, sizeof mask)) return "the grid's data ends early";
    uint64_t active = 0;
    for (uint64_t m : mask) active += uint64_t(__builtin_popcountll(m));
    if (active != layout.leafActive[i]) return "its value mask differs from the topology's";
    ValuesRecord rec;
    const std::string why = walkValues(in, compression, half, valueSize, kLeafValues, active, rec);
    if (!why.empty()) return why;
    if (delayed.present) {
        if ((compression & openvdb::io::COMPRESS_ACTIVE_MASK) && delayed.codes[i] != rec.code)
            return "its code differs from the delayed-load metadata";
        if ((compression & (openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ZIP)) && rec.hasChunk &&
            !delayed.sizes.empty() && uint64_t(delayed.sizes[i]) != rec.chunkBytes)
            return "its size differs from the delayed-load metadata";
    }
    return "";
}

// Where each leaf's record starts (and, last, where the records end), from the delayed-load metadata's
// codes and chunk sizes: a record is its value mask, its code, what the code stores (inactive values, a
// selection mask), then its chunk. Empty where the metadata cannot say: none, values not in chunks,
// or half floats (an empty leaf of those stores no chunk).
std::vector<uint64_t> leafStarts(const DelayedLoadSizes& d, size_t leaves, uint64_t first, uint64_t end,
                                 uint32_t compression, bool half, uint64_t valueSize)
{
    const bool maskCompressed = compression & openvdb::io::COMPRESS_ACTIVE_MASK;
    if (!d.present || half || leaves == 0 || !(compression & (openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ZIP)))
        return {};
    std::vector<uint64_t> at(leaves + 1);
    at[0] = first;
    for (size_t i = 0; i < leaves; ++i) {
        const int8_t code = maskCompressed ? d.codes[i] : 6;
        if (d.sizes[i] < 8) return {};
        at[i + 1] = at[i] + 64 + 1 + storedBeforeChunk(code, valueSize, kLeafValues) + uint64_t(d.sizes[i]);
        if (at[i + 1] > end) return {};
    }
    return at;
}

// The leaf records [first, last) walked in runs on all of the run's threads, each run by a reader of its
// own from where `at` says it starts: true when every record is sound and starts where `at` says. On
// false the records are walked again one after another, which finds the first fault and names it as always.
bool walkLeavesAtOnce(const std::string& path, uint64_t fileSize, uint64_t end, const std::vector<uint64_t>& at,
                      size_t first, size_t last, const VdbGridLayout& layout, uint32_t compression, bool half,
                      uint64_t valueSize, const DelayedLoadSizes& delayed)
{
    constexpr size_t kRun = 16384;  // leaves a reader walks: a few MB of records
    std::atomic<bool> sound{true};
    if (first >= last) return true;
    tbb::parallel_for(tbb::blocked_range<size_t>(first, last, kRun), [&](const tbb::blocked_range<size_t>& r) {
        if (!sound) return;
        BoundedReader in(path, fileSize);
        in.setLimit(end);
        if (!in.ok() || !in.seek(at[r.begin()])) {
            sound = false;
            return;
        }
        for (size_t i = r.begin(); i != r.end(); ++i)
            if (in.pos() != at[i] || !walkLeaf(in, i, layout, compression, half, valueSize, delayed).empty()) {
                sound = false;
                return;
            }
        if (in.pos() != at[r.end()]) sound = false;
    });
    return sound;
}

// A hash of the leaves' origins, active counts and record starts, a word at a time (multiply and
// fold): what two processes' walks of the same stored tree agree on.
uint64_t treeDigest(const VdbGridLayout& layout, const std::vector<uint64_t>& at)
{
    uint64_t h = at.size();
    for (size_t i = 0; i < layout.leafOrigins.size(); ++i) {
        const auto& o = layout.leafOrigins[i];
        mixInto(h, uint64_t(uint32_t(o[0])) << 32 | uint32_t(o[1]));
        mixInto(h, uint64_t(uint32_t(o[2])) << 32 | layout.leafActive[i]);
    }
    for (uint64_t a : at) mixInto(h, a);
    return h;
}

// Walks a grid's tree from its topology (where walkGridHeader leaves `in`) to the end of its last leaf
// record: the topology node by node, then every leaf's record (walkLeaf) in the topology's leaf order.
// `e` gives where the topology must end and the grid must end; a streamed entry learns them here.
// With a share of several parts, this process walks its part of the records at once, and every part's
// verdict decides whether all records are walked one after another (LeafWalkShare).
void walkTree(const std::string& path, BoundedReader& in, GridEntry& e, uint32_t compression, bool half,
              uint64_t valueSize, const DelayedLoadSizes& delayed, VdbGridLayout& layout,
              const LeafWalkShare* share = nullptr)
{
    const std::string& name = e.name;
    const bool locate = e.streamed && e.blockPos == 0;
    TopologyWalk topo{path, name, in, compression, half, valueSize, layout};
    if (delayed.present) {  // the leaf count the metadata states (bounded by the grid's bytes when it was read)
        layout.leafOrigins.reserve(delayed.codes.size());
        layout.leafActive.reserve(delayed.codes.size());
    }
    topo.root();
    if (locate) e.blockPos = in.pos();
    if (in.pos() != e.blockPos)
        damaged(path, "grid '" + name + "': topology ends at byte " + std::to_string(in.pos()) + ", its data starts at " +
                          std::to_string(e.blockPos));

    const size_t leaves = layout.leafOrigins.size();
    const bool chunked = compression & (openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ZIP);
    if (delayed.present && leaves > 0 &&
        (delayed.codes.size() != leaves || (chunked && delayed.sizes.size() != leaves)))
        damaged(path, "grid '" + name + "': delayed-load metadata lists " + std::to_string(delayed.codes.size()) +
                          " leaves, the topology has " + std::to_string(leaves));
    in.setLimit(e.endPos);
    if (!in.seek(e.blockPos)) damaged(path, "grid '" + name + "' ends early");
    // A file with offsets and delayed-load metadata (what OpenVDB writes) says where every record
    // starts: its millions of leaves are walked on all threads, the way they are read later.
    std::vector<uint64_t> at =
        locate ? std::vector<uint64_t>{} : leafStarts(delayed, leaves, e.blockPos, e.endPos, compression, half, valueSize);
    const uint64_t digest = treeDigest(layout, at);
    const bool located = !at.empty() && at.back() == e.endPos;
    const bool split = share && share->parts > 1 && located;
    const size_t first = split ? leaves * share->part / share->parts : 0;
    const size_t last = split ? leaves * (share->part + 1) / share->parts : leaves;
    bool sound = located && walkLeavesAtOnce(path, in.size(), e.endPos, at, first, last, layout, compression, half,
                                             valueSize, delayed);
    if (split) sound = share->allSound(sound, digest);
    if (sound) {
        in.seek(e.endPos);
        if (split) layout.recordStarts = at;  // and KeptRecordsWalk keeps them too
        else layout.recordStarts = std::move(at);
    } else {
        layout.recordStarts.resize(leaves + 1);
        for (size_t i = 0; i < leaves; ++i) {
            layout.recordStarts[i] = in.pos();
            const std::string why = walkLeaf(in, i, layout, compression, half, valueSize, delayed);
            if (!why.empty()) throw damagedLeaf(path, name, layout.leafOrigins[i], why);
        }
        layout.recordStarts[leaves] = in.pos();
    }
    if (locate) e.endPos = in.pos();
    if (in.pos() != e.endPos)
        damaged(path, "grid '" + name + "': leaf data ends at byte " + std::to_string(in.pos()) + ", the grid at " +
                          std::to_string(e.endPos));
    layout.digest = digest;
    layout.leafCount = leaves;
    // Where the records could not be split, the whole walk's verdict (it got here: sound).
    if (share && !split) share->allSound(true, digest);
    if (split && sound) {
        // What KeptRecordsWalk needs, moved rather than copied (a rank's set-up holds the whole topology
        // then): the record starts, the leaves' active counts, the codes. Not the origins (the tree
        // OpenVDB reads lists them in the same order: a hash checks it) nor the chunk sizes (the starts
        // follow from them, and a record that ends elsewhere is caught).
        auto r = std::make_shared<LeafRecords>();
        r->path = path;
        r->grid = name;
        r->fileSize = in.size();
        r->compression = compression;
        r->half = half;
        r->valueSize = valueSize;
        r->delayed.present = delayed.present;
        r->delayed.codes = delayed.codes;
        r->at = std::move(at);
        for (const auto& o : layout.leafOrigins) addToLeafOrder(r->order, o);
        std::vector<std::array<int32_t, 3>>().swap(layout.leafOrigins);
        r->layout.leafActive = std::move(layout.leafActive);
        r->first = first;
        r->last = last;
        layout.unwalked = std::move(r);
    }
}

// A file written as a stream (io::Stream) states no grid offsets, and OpenVDB reads every grid in it,
// voxels included, as it opens the file. So every grid is walked here in turn (descriptor, header,
// tree) to find where it ends and the next begins; a grid whose tree or transform this walk does not
// know cannot be checked, and the file is refused rather than read unchecked.
void walkStreamedGrids(const std::string& path, BoundedReader& in, int32_t grids, FileEntries& out)
{
    const uint64_t size = in.pos() + in.left();
    for (int32_t g = 0; g < grids; ++g) {
        GridEntry e;
        int64_t unusedOffsets[3];
        in.setLimit(size);
        if (!readDescriptor(in, e) || !in.bytes(unusedOffsets, sizeof unusedOffsets))
            damaged(path, "descriptor of grid " + std::to_string(g + 1) + " of " + std::to_string(grids) + " ends early");
        e.gridPos = in.pos();
        e.endPos = size;
        e.streamed = true;
        const std::string refused = path + ": grid '" + e.name + "' of a file written without grid offsets (as a stream) ";
        uint32_t compression = 0;
        DelayedLoadSizes delayed;
        if (!walkGridHeader(path, in, e, compression, &delayed))
            throw InputError(refused + "has a transform that cannot be checked before OpenVDB reads the whole file");
        if (e.parent.empty()) {
            bool half = false;
            uint64_t valueSize = 0;
            if (!treeFormat(e.type, half, valueSize))
                throw InputError(refused + "is of type " + printable(e.type) +
                                 ": only float and double grids can be checked before OpenVDB reads the whole file;"
                                 " save it again as a file with offsets (openvdb::io::File)");
            in.setLimit(size);
            VdbGridLayout layout;
            walkTree(path, in, e, compression, half, valueSize, delayed, layout);
        } else {
            e.endPos = in.pos();  // an instance stores its metadata and transform only
        }
        out.grids.push_back(std::move(e));
    }
}

} // namespace

VdbGridLayout checkVdbGridData(const std::string& path, const VdbFileEntries& f, const std::string& gridName,
                               const LeafWalkShare* share)
{
    VdbGridLayout layout;
    if (!f.checkable) return layout;
    const GridEntry* e = nullptr;
    for (const GridEntry& g : f.grids)
        if (g.uniqueName == gridName) { e = &g; break; }
    if (!e)
        for (const GridEntry& g : f.grids)
            if (g.plain == gridName) { e = &g; break; }
    if (!e) return layout;
    GridEntry tree = *e;
    if (!e->parent.empty()) {  // an instance reads its parent's tree
        const GridEntry* p = nullptr;
        for (const GridEntry& g : f.grids)
            if (g.uniqueName == e->parent) p = &g;
        if (!p) return layout;
        tree = *p;
        tree.name = e->name;
    }
    bool half = false;
    uint64_t valueSize = 0;
    if (!treeFormat(tree.type, half, valueSize) || tree.blockPos == 0) return layout;

    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) return layout;
    BoundedReader in(path, uint64_t(st.st_size));
    uint32_t compression = 0;
    // The delayed-load metadata checkVdbFileStructure decoded, else decoded here.
    DelayedLoadSizes decoded;
    if (!walkGridHeader(path, in, tree, compression, tree.delayed ? nullptr : &decoded)) return layout;
    const uint64_t topologyPos = in.pos();
    walkTree(path, in, tree, compression, half, valueSize, tree.delayed ? *tree.delayed : decoded, layout, share);
    std::vector<uint16_t>().swap(layout.leafActive);
    layout.topologyPos = e->parent.empty() && !e->streamed ? topologyPos : 0;
    layout.fileVersion = f.version;
    layout.compression = compression;
    layout.half = half;
    layout.checked = true;
    return layout;
}

void KeptRecordsWalk::leaf(const std::array<int32_t, 3>& origin, bool reads)
{
    const size_t i = mLeaves++;
    addToLeafOrder(mOrder, origin);
    if (reads && (i < mRecords.first || i >= mRecords.last)) mRead.push_back({i, origin});
}

void KeptRecordsWalk::walk()
{
    const LeafRecords& r = mRecords;
    if (mLeaves + 1 != r.at.size() || mOrder != r.order)
        throw InputError(r.path + ": truncated or damaged OpenVDB file (grid '" + r.grid +
                         "': its leaves are not the stored ones in the stored order)");
    // Each leaf from where its record starts, on all threads, reading no further than the end of its
    // run of consecutive kept records; the first fault in file order is named.
    std::vector<uint64_t> runEnd(mRead.size());
    for (size_t k = mRead.size(); k-- > 0;)
        runEnd[k] = k + 1 < mRead.size() && mRead[k + 1].first == mRead[k].first + 1 ? runEnd[k + 1] : r.at[mRead[k].first + 1];
    const auto fault = [&](BoundedReader& in, size_t k) -> std::string {
        const size_t i = mRead[k].first;
        in.setLimit(runEnd[k]);
        if (!in.seek(r.at[i])) return "the grid's data ends early";
        std::string why = walkLeaf(in, i, r.layout, r.compression, r.half, r.valueSize, r.delayed);
        if (why.empty() && in.pos() != r.at[i + 1]) why = "its size differs from the delayed-load metadata";
        return why;
    };
    constexpr size_t kRun = 4096;
    std::atomic<size_t> firstBad{mRead.size()};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, mRead.size(), kRun), [&](const tbb::blocked_range<size_t>& b) {
        BoundedReader in(r.path, r.fileSize);
        for (size_t k = b.begin(); k != b.end() && k < firstBad.load(); ++k)
            if (!in.ok() || !fault(in, k).empty()) {
                for (size_t seen = firstBad.load(); k < seen && !firstBad.compare_exchange_weak(seen, k);) {
                }
                return;
            }
    });
    const size_t bad = firstBad.load();
    if (bad == mRead.size()) return;
    BoundedReader in(r.path, r.fileSize);
    const std::string why = in.ok() ? fault(in, bad) : "cannot open file for reading";
    throw damagedLeaf(r.path, r.grid, mRead[bad].second, why);
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
    openvdb::Mat4d m;
    try {
        m = xform.baseMap()->getAffineMap()->getMat4();  // a scale map builds its affine map here
    } catch (const std::exception&) {
        throw InputError("has a singular transform (OpenVDB cannot invert its map)");
    }
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c)
            if (!std::isfinite(m(r, c))) throw InputError("has a transform with non-finite coefficients");
    const double det = m.getMat3().det();
    if (!(std::abs(det) >= 1e-300) || !std::isfinite(1.0 / det))
        throw InputError("has a singular transform (not invertible: determinant " + std::to_string(det) + ")");
}

} // namespace vdb_isosimp

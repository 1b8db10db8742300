// Dense-volume headers: NRRD (.nrrd attached, .nhdr detached), MetaImage (.mhd/.mha), NIfTI-1
// (.nii, .nii.gz, .hdr/.img) and bare raw files, all parsed into one RawVolumeInfo that says where
// the voxel bytes are, how they are encoded and where the voxels sit in space.
//
// Conventions shared by every format:
//  - dims are (X, Y, Z) with X varying fastest in the data, as all three formats store it.
//  - A voxel (i, j, k) is centred at  origin + direction * (spacing ∘ (i, j, k)),  where the columns
//    of `direction` are the axis directions (not necessarily orthonormal) and spacing > 0.
//  - World coordinates are the file's own: NIfTI's RAS+, MetaImage's LPS, whatever NRRD's `space`
//    says. They are taken as written, never converted between conventions.
//  - The voxel data start `fileOffset` bytes into `dataFile`; with a compressed encoding the stream
//    starting there is inflated and `decodedSkip` further bytes of decoded data are dropped.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

namespace vdb_isosimp {

/// Every error of the converter: `file` is the file concerned (input header, its data file or the
/// output), what() the problem in a few words, without the file name.
class RawInputError : public std::runtime_error {
public:
    RawInputError(std::string file, const std::string& problem)
        : std::runtime_error(problem), mFile(std::move(file)) {}
    const std::string& file() const { return mFile; }

private:
    std::string mFile;
};

enum class ScalarType { U8, I8, U16, I16, U32, I32, F32, F64 };
enum class ByteOrder { Little, Big };
enum class Encoding { Raw, Gzip, Zlib };
enum class VolumeFormat { Raw, Nrrd, MetaImage, Nifti, Dicom, Tiff };

/// Size of one value in bytes.
std::size_t scalarSize(ScalarType t);
/// Short name: "u8", "i16", "f32", ...
const char* scalarName(ScalarType t);
/// Parses the short names (u8|i8|u16|i16|u32|i32|f32|f64) and the usual long ones (uint8, uchar,
/// "unsigned short", int16_t, float, double, ...). Returns nothing for an unknown name.
std::optional<ScalarType> parseScalarType(const std::string& name);
const char* byteOrderName(ByteOrder b);
const char* encodingName(Encoding e);
const char* formatName(VolumeFormat f);
/// The byte order of this machine.
ByteOrder hostByteOrder();

struct RawVolumeInfo {
    VolumeFormat format = VolumeFormat::Raw;
    std::string headerFile;              ///< the file the user named
    std::string dataFile;                ///< where the voxel bytes are (same file when attached)
    std::array<uint64_t, 3> dims{{0, 0, 0}};
    ScalarType type = ScalarType::U8;
    ByteOrder byteOrder = ByteOrder::Little;
    Encoding encoding = Encoding::Raw;
    uint64_t fileOffset = 0;             ///< bytes of dataFile before the (possibly compressed) data
    uint64_t decodedSkip = 0;            ///< decoded bytes dropped before the voxels (compressed only)
    std::array<double, 3> spacing{{1.0, 1.0, 1.0}};
    /// direction[r][c]: component r of the direction of axis c (columns are axis directions).
    std::array<std::array<double, 3>, 3> direction{{{{1, 0, 0}}, {{0, 1, 0}}, {{0, 0, 1}}}};
    std::array<double, 3> origin{{0.0, 0.0, 0.0}};
    double scale = 1.0;                  ///< value = stored * scale + intercept (NIfTI scl_*)
    double intercept = 0.0;

    uint64_t voxelCount() const;         ///< X*Y*Z (dims validated not to overflow)
    uint64_t dataBytes() const;          ///< voxelCount * scalarSize
};

/// Layout of a bare raw file, given on the command line (the header formats ignore it).
struct RawLayout {
    std::optional<std::array<uint64_t, 3>> dims;
    std::optional<ScalarType> type;
    ByteOrder byteOrder = ByteOrder::Little;
    uint64_t skip = 0;                   ///< bytes before the data (header of an unknown format)
};

/// Format from the file name: .nrrd/.nhdr, .mhd/.mha, .nii/.nii.gz/.hdr, anything else raw.
VolumeFormat detectFormat(const std::string& path);

/// Reads the header of `path` (or takes `layout` for a raw file), validates it (dims > 0 and not
/// overflowing, known type, spacing > 0, data present and, for uncompressed data, exactly as long as
/// dims × type size) and returns where and what the voxels are. Throws RawInputError.
RawVolumeInfo readVolumeInfo(const std::string& path, const RawLayout& layout = {});

/// Checks dims (each in [1, 2^31-1], product × size within 64 bits). Throws RawInputError.
void validateDims(const std::string& file, const std::array<uint64_t, 3>& dims, ScalarType t);

/// Sequential reader of the bytes of a file from an offset on, inflating them when the encoding is
/// gzip or zlib (both detected from the stream header; concatenated gzip members are read on).
/// Reads in large blocks; never holds more than one input block and one zlib window.
class DataStream {
public:
    /// Opens `path` and positions it at `offset`. `total` is the number of decoded bytes the caller
    /// means to read (for the error messages only). Throws RawInputError.
    DataStream(const std::string& path, uint64_t offset, Encoding encoding, uint64_t total);
    ~DataStream();
    DataStream(const DataStream&) = delete;
    DataStream& operator=(const DataStream&) = delete;

    /// Reads exactly n bytes; throws RawInputError ("truncated", "gzip stream ends early", corrupt
    /// data, read error) when they cannot be had.
    void readExact(void* dst, std::size_t n);
    /// Drops n decoded bytes (same errors as readExact).
    void skip(uint64_t n);
    /// Decoded bytes delivered or skipped so far.
    uint64_t position() const { return mPos; }

private:
    std::size_t readSome(void* dst, std::size_t n); // < n only at the end of the data
    std::size_t fillInput();

    std::string mPath;
    Encoding mEncoding;
    uint64_t mTotal;
    uint64_t mPos = 0;
    int mFd = -1;
    void* mZ = nullptr;            // z_stream when compressed
    std::string mIn;               // compressed input block
    bool mInputEof = false;
    bool mStreamEnd = false;
};

} // namespace vdb_isosimp

// Volumes stored as a stack of 2D images: a DICOM series (a folder of files, one slice each) and a TIFF
// stack (one multi-page file, or a folder of single-page files). A SliceSource knows the volume's
// geometry up front (from the headers of every slice, read once) and delivers the voxels z slice by z
// slice, so raw_converter streams them in slabs like a raw file.
//
// Index (i, j, k) = (column, row, slice): i runs along a row of an image, j down its rows, k over the
// slices in increasing position (DICOM: along the slice normal; TIFF: page order, or the natural order
// of the file names in a folder).
#pragma once

#include "raw_header.h"

#include <cstdint>
#include <memory>
#include <string>

namespace vdb_isosimp {

struct SliceSourceOptions {
    /// DICOM: the SeriesInstanceUID to read when the folder holds several series (empty: the only one).
    std::string series;
};

class SliceSource {
public:
    virtual ~SliceSource() = default;
    /// Geometry, value type (host byte order) and rescaling of the volume; headerFile is the input.
    const RawVolumeInfo& info() const { return mInfo; }
    /// Fills dst with slices [z0, z0 + n): n × X × Y values of info().type in host byte order, x fastest.
    /// Throws RawInputError naming the slice's file (and page) on a truncated or undecodable image.
    virtual void readSlices(uint64_t z0, uint64_t n, unsigned char* dst) = 0;
    /// For the summary line: "DICOM series 1.2.3 (40 files, JPEG Lossless)", "TIFF stack (120 pages)".
    virtual std::string describe() const = 0;

protected:
    RawVolumeInfo mInfo;
};

/// True when `input` is read through a SliceSource: a folder, or a file named .tif/.tiff.
bool isSliceStackInput(const std::string& input);

/// Opens a folder (DICOM series or single-page TIFFs, decided by the files' signatures; files that are
/// neither are skipped) or a multi-page TIFF, reading every slice's header. Throws RawInputError
/// (a folder with no image, mixed sizes or types, several series without options.series, ...).
std::unique_ptr<SliceSource> openSliceSource(const std::string& input, const SliceSourceOptions& options);

/// "2" < "10": compares runs of digits by value, everything else byte by byte (file names of slices).
bool naturalLess(const std::string& a, const std::string& b);

} // namespace vdb_isosimp

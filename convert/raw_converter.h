// Streaming conversion of a dense volume (raw, NRRD, MetaImage, NIfTI-1; see raw_header.h) or an image
// stack (a DICOM series or a TIFF stack; see slice_source.h) into a sparse openvdb::FloatGrid.
//
// The input is read in z slabs one leaf thick (8 z rows of X*Y values), a few slabs in flight at a
// time, so peak memory is a few slabs plus the output tree whatever the input size. Each slab is
// cut into 8x8x8 leaves in parallel (tbb::parallel_for):
//  - a leaf whose values all lie within `tolerance` of the background adds nothing (inactive
//    background),
//  - a whole leaf (inside the volume) whose values span at most 2*tolerance becomes one active tile
//    (at leaf level) holding the middle of that span,
//  - any other leaf is stored as an OpenVDB leaf node filled directly (no per-voxel accessor);
//    its voxels within `tolerance` of the background are inactive and hold the background exactly.
// Hence every active value, and every inactive one, is within `tolerance` of the input value (after
// scaling and clamping). Leaves at the far X/Y/Z borders keep the voxels outside the volume
// inactive, so the active region never grows past the input. Finally the tree is pruned losslessly
// (tools::prune with tolerance 0) so equal tiles merge into larger ones.
//
// The grid value type is float: every input type is converted to float after scaling (f64 inputs
// and 32-bit integers beyond 2^24 lose precision accordingly).
//
// Voxel (i, j, k) of the input is voxel (i, j, k) of the grid; the grid's linear transform maps it to
// origin + direction * (spacing ∘ (i, j, k)), the voxel centre in the file's world coordinates.
#pragma once

#include "raw_header.h"
#include "slice_source.h"

#include <openvdb/openvdb.h>

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

namespace vdb_isosimp {

enum class RawGridClass { Fog, LevelSet };

struct RawConvertOptions {
    /// Layout of a bare raw file: --dims and --type are required there, byte order defaults to
    /// little endian, skip to 0. Files with a header (NRRD, MetaImage, NIfTI) ignore it.
    RawLayout layout;
    /// Override the voxel spacing / origin of any input (default: the header's, or 1,1,1 and
    /// 0,0,0 for raw files). With spacing overridden the header's axis directions are kept.
    std::optional<std::array<double, 3>> spacing;
    std::optional<std::array<double, 3>> origin;
    /// DICOM folder holding several series: the SeriesInstanceUID to convert (default: the only one).
    std::string series;
    /// Grid name; empty (default) means "density" for fog volumes and "surface" for level sets.
    std::string name;
    /// Grid class written to the file: fog volume (default) or level set.
    RawGridClass gridClass = RawGridClass::Fog;
    /// Background (the value of inactive voxels). Default: 0 for fog volumes; for level sets
    /// 3 × the smallest voxel spacing (OpenVDB's usual half width of 3 voxels). For level sets the
    /// inside (values <= -background) becomes inactive -background, the outside inactive
    /// +background.
    std::optional<double> background;
    /// Values within this distance of one another merge into tiles, values within it of the
    /// background become inactive (see above). Default 0: lossless.
    double tolerance = 0.0;
    /// Clamp every value (after scaling) into [lo, hi]. Default: no clamping.
    std::optional<std::array<double, 2>> clamp;
    /// Store the grid's values as 16-bit half floats in the file (default false: 32-bit floats).
    bool half = false;
    /// Slabs read ahead of the one being converted (memory: (readAhead + 1) slabs). Default 2.
    int readAhead = 2;
    /// Called after every slab with (slabs done, slab count), from the converting thread.
    std::function<void(uint64_t, uint64_t)> progress;
};

struct RawConvertStats {
    RawVolumeInfo info;             ///< what was read (after overrides)
    std::string source;             ///< image stacks: what was read ("DICOM series 1.2.3, 40 files, ..."), else empty
    uint64_t activeVoxels = 0;      ///< in the final tree (tiles counted voxel by voxel)
    uint64_t leafCount = 0;         ///< leaf nodes in the final tree
    uint64_t tileCount = 0;         ///< active tiles in the final tree (any level)
    double seconds = 0;             ///< wall time of the whole conversion (header to file)
    uint64_t peakRssBytes = 0;      ///< peak resident memory of the process so far
    uint64_t inputBytes = 0;        ///< decoded voxel bytes read
};

/// Reads the header (or takes the raw layout; for an image stack, every slice's header), applies the
/// spacing/origin overrides and validates.
RawVolumeInfo resolveVolumeInfo(const std::string& input, const RawConvertOptions& options);

/// The grid's transform for a volume: voxel (i,j,k) -> origin + direction * (spacing ∘ ijk).
openvdb::math::Transform::Ptr makeTransform(const RawVolumeInfo& info);

/// Converts `input` into a grid held in memory (name, class, transform set). Throws RawInputError.
openvdb::FloatGrid::Ptr convertToGrid(const std::string& input, const RawConvertOptions& options,
                                      RawConvertStats* stats = nullptr);

/// Converts `input` and writes the grid to `output` (.vdb): written to `output.tmp.<pid>` and
/// renamed over `output` only on success; nothing is left behind on failure. Checks that the output
/// can be written before reading any voxel. Throws RawInputError (file = input or output).
RawConvertStats convertRawToVdb(const std::string& input, const std::string& output, const RawConvertOptions& options);

/// Peak resident set size of this process in bytes (getrusage).
uint64_t peakRssBytes();

} // namespace vdb_isosimp

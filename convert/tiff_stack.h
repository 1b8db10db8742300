// TIFF stacks through libtiff (Debian's libtiff-dev): one multi-page file (a light-sheet or confocal
// stack as ImageJ/Fiji, tifffile or a microscope writes it) or a folder of single-page files sorted by
// name in natural order (slice_2 before slice_10). One sample per pixel of 8, 16 or 32-bit integers
// (unsigned or signed) or 32/64-bit floats; strips or tiles, any compression libtiff decodes. Pages
// marked as reduced-resolution copies (thumbnails) are skipped.
//
// Voxel size, in micrometres (the world unit of a microscopy .vdb):
//  - ImageJ's description ("ImageJ=...", "unit=micron", "spacing=4.0") with the resolution tags:
//    x = 1/XResolution, y = 1/YResolution and z = spacing, in ImageJ's unit converted to µm
//    (nm, µm/um/micron, mm, cm, m; no unit: taken as µm);
//  - otherwise resolution tags in pixels per centimetre (ResolutionUnit 3): 10^4/XResolution µm, z 1;
//  - otherwise (no tags, or the inch-based 72 dpi of print software) 1, 1, 1: --spacing sets it.
// Pages are read one slab at a time (the file is read, not memory-mapped, so the resident memory stays
// a few slabs whatever the stack's size).
#pragma once

#include "slice_source.h"

#include <memory>
#include <string>
#include <vector>

namespace vdb_isosimp {

/// True when the file starts with a TIFF signature (II*\0, MM\0*, or BigTIFF's II+\0 / MM\0+).
bool looksLikeTiff(const std::string& path);

/// A multi-page TIFF file. Throws RawInputError.
std::unique_ptr<SliceSource> openTiffFile(const std::string& path);

/// A folder of TIFF files, one slice each (each file's first full-resolution page), sorted by name in
/// natural order. Throws RawInputError.
std::unique_ptr<SliceSource> openTiffFolder(const std::string& folder, std::vector<std::string> files);

} // namespace vdb_isosimp

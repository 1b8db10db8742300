// DICOM series through DCMTK (Debian's libdcmtk-dev): a folder of single-frame images of one series
// becomes a volume. Files with and without the 128-byte preamble and file-meta group are read alike;
// compressed transfer syntaxes are decoded by DCMTK's codecs (JPEG, JPEG-LS, RLE; deflate in the
// parser), others are refused by name.
//
// Geometry, in DICOM's patient coordinates (LPS: +x to the patient's left, +y to the back, +z to the
// head), kept as written:
//  - slices are sorted by ImagePositionPatient · n, n = row direction × column direction of
//    ImageOrientationPatient, and must be evenly spaced along a line (1% of the step);
//  - axis i (columns) runs along IOP's first triplet with spacing PixelSpacing[1], axis j (rows) along
//    the second with PixelSpacing[0], axis k from the first slice's position to the last's (a tilted
//    gantry gives a sheared, still linear, transform);
//  - voxel (0, 0, 0) is centred at the first slice's ImagePositionPatient.
// Values: stored values (BitsStored bits at HighBit, signed when PixelRepresentation is 1) times
// RescaleSlope plus RescaleIntercept (Hounsfield units for CT); when every slice has the same slope and
// intercept the converter applies them, otherwise the slices are delivered as f32 already rescaled.
#pragma once

#include "slice_source.h"

#include <memory>
#include <string>
#include <vector>

namespace vdb_isosimp {

/// True when the file starts like DICOM: "DICM" at byte 128 (with preamble), or a first element of
/// group 0002 or 0008 in little-endian encoding (datasets written without preamble and meta group).
bool looksLikeDicom(const std::string& path);

/// Reads the headers of `files` (all in `folder`, each already found to look like DICOM), picks the
/// series (`series`, or the only one), checks and sorts its slices. Throws RawInputError.
std::unique_ptr<SliceSource> openDicomSeries(const std::string& folder, const std::vector<std::string>& files,
                                             const std::string& series);

} // namespace vdb_isosimp

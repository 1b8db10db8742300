// make_dicom_series: writes a folder of single-frame CT slices the way a scanner exports a series (one
// file per slice, 16-bit signed values, RescaleIntercept -1024: Hounsfield units), for timing raw2vdb's
// DICOM reader. The sample is a ball of textured soft tissue (about +400 HU) in air (-1000 HU).
//   make_dicom_series FOLDER [--size W,H,SLICES] [--deflated]
#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

int main(int argc, char** argv)
{
    CLI::App app{"make_dicom_series: write a CT series, one DICOM file per slice (a ball of tissue in air)"};
    std::string folder;
    std::vector<unsigned> size{512, 512, 300};
    bool deflated = false;
    app.add_option("folder", folder, "output folder (created; files IM0000, IM0001, ...)")->required();
    app.add_option("--size", size, "columns, rows, slices (default 512,512,300)")->expected(3)->delimiter(',');
    app.add_flag("--deflated", deflated, "Deflated Explicit VR Little Endian instead of Explicit VR Little Endian");
    CLI11_PARSE(app, argc, argv);
    const unsigned W = size[0], H = size[1], D = size[2];
    if (W == 0 || H == 0 || D == 0 || W > 65535 || H > 65535) {
        std::fprintf(stderr, "make_dicom_series: --size %u,%u,%u: columns and rows in 1..65535, at least one slice\n", W, H, D);
        return 2;
    }
    std::filesystem::create_directories(folder);
    const std::string series = "1.2.826.0.1.3680043.9.7777.9";
    const E_TransferSyntax xfer = deflated ? EXS_DeflatedLittleEndianExplicit : EXS_LittleEndianExplicit;
    const double cx = 0.5 * W, cy = 0.5 * H, cz = 0.5 * D, r = 0.35 * std::min({W, H, D});
    std::vector<Uint16> pixels(size_t(W) * H);
    for (unsigned k = 0; k < D; ++k) {
        DcmFileFormat ff;
        DcmDataset* d = ff.getDataset();
        d->putAndInsertString(DCM_SOPClassUID, UID_CTImageStorage);
        d->putAndInsertString(DCM_SOPInstanceUID, (series + "." + std::to_string(k + 1)).c_str());
        d->putAndInsertString(DCM_Modality, "CT");
        d->putAndInsertString(DCM_SeriesInstanceUID, series.c_str());
        d->putAndInsertString(DCM_InstanceNumber, std::to_string(k + 1).c_str());
        d->putAndInsertString(DCM_ImagePositionPatient, ("-128\\-128\\" + std::to_string(0.5 * k)).c_str());
        d->putAndInsertString(DCM_ImageOrientationPatient, "1\\0\\0\\0\\1\\0");
        d->putAndInsertString(DCM_PixelSpacing, "0.5\\0.5");
        d->putAndInsertString(DCM_SliceThickness, "0.5");
        d->putAndInsertString(DCM_RescaleSlope, "1");
        d->putAndInsertString(DCM_RescaleIntercept, "-1024");
        d->putAndInsertUint16(DCM_Rows, Uint16(H));
        d->putAndInsertUint16(DCM_Columns, Uint16(W));
        d->putAndInsertUint16(DCM_SamplesPerPixel, 1);
        d->putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME2");
        d->putAndInsertUint16(DCM_BitsAllocated, 16);
        d->putAndInsertUint16(DCM_BitsStored, 16);
        d->putAndInsertUint16(DCM_HighBit, 15);
        d->putAndInsertUint16(DCM_PixelRepresentation, 1);
        for (unsigned y = 0; y < H; ++y)
            for (unsigned x = 0; x < W; ++x) {
                const bool inside = std::hypot(x - cx, y - cy, k - cz) < r;
                const int hu = inside ? 400 + int(30 * std::sin(0.1 * x) * std::cos(0.13 * y)) : -1000;
                pixels[size_t(y) * W + x] = Uint16(int16_t(hu + 1024));
            }
        d->putAndInsertUint16Array(DCM_PixelData, pixels.data(), static_cast<unsigned long>(pixels.size()));
        char name[32];
        std::snprintf(name, sizeof name, "/IM%04u", k);
        const OFCondition c = ff.saveFile((folder + name).c_str(), xfer);
        if (c.bad()) {
            std::fprintf(stderr, "make_dicom_series: cannot write %s%s: %s\n", folder.c_str(), name, c.text());
            return 1;
        }
    }
    std::printf("make_dicom_series: %u slices of %ux%u in %s (%s)\n", D, W, H, folder.c_str(), DcmXfer(xfer).getXferName());
    return 0;
}

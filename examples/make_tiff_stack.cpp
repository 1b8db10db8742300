// make_tiff_stack: writes a multi-page 16-bit TIFF the way ImageJ/Fiji saves a light-sheet stack
// (uncompressed strips, "ImageJ=" description with unit=micron and spacing=, resolution tags), for the
// raw2vdb benchmark (scripts/bench_tiff_stack.sh). The sample is an ellipsoid of textured signal
// (values 100..4195) filling the middle of the volume over a background of 0, as after background
// subtraction: about 18% of the voxels are signal.
//   make_tiff_stack OUT.tif [--size W,H,D] [--spacing XY,Z]
#include <tiffio.h>

#include <CLI/CLI.hpp>

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

int main(int argc, char** argv)
{
    CLI::App app{"make_tiff_stack: write a multi-page 16-bit ImageJ TIFF (an ellipsoid of signal over 0)"};
    std::string out;
    std::vector<uint32_t> size{1024, 1024, 512};
    std::vector<double> spacing{0.406, 2.0};
    app.add_option("output", out, "output .tif")->required();
    app.add_option("--size", size, "width, height, pages (default 1024,1024,512: 1 GiB)")->expected(3)->delimiter(',');
    app.add_option("--spacing", spacing, "pixel size and page spacing in micrometres (default 0.406,2)")->expected(2)->delimiter(',');
    CLI11_PARSE(app, argc, argv);
    const uint32_t W = size[0], H = size[1], D = size[2];
    const uint64_t bytes = uint64_t(W) * H * D * 2;

    TIFF* tif = TIFFOpen(out.c_str(), bytes >= (uint64_t(4) << 30) - (uint64_t(64) << 20) ? "w8" : "w");  // BigTIFF near 4 GiB
    if (!tif) {
        std::fprintf(stderr, "make_tiff_stack: cannot write %s\n", out.c_str());
        return 1;
    }
    char desc[256];
    std::snprintf(desc, sizeof desc, "ImageJ=1.54f\nimages=%u\nslices=%u\nunit=micron\nspacing=%g\nloop=false\n", D, D, spacing[1]);
    std::vector<uint16_t> row(W);
    const double cx = 0.5 * W, cy = 0.5 * H, cz = 0.5 * D, rx = 0.35 * W, ry = 0.35 * H, rz = 0.35 * D;
    for (uint32_t z = 0; z < D; ++z) {
        TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, W);
        TIFFSetField(tif, TIFFTAG_IMAGELENGTH, H);
        TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, uint16_t(16));
        TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, uint16_t(1));
        TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
        TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
        TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_NONE);
        TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, H);  // ImageJ writes one strip per page
        TIFFSetField(tif, TIFFTAG_XRESOLUTION, float(1.0 / spacing[0]));
        TIFFSetField(tif, TIFFTAG_YRESOLUTION, float(1.0 / spacing[0]));
        TIFFSetField(tif, TIFFTAG_RESOLUTIONUNIT, uint16_t(RESUNIT_NONE));
        if (z == 0) TIFFSetField(tif, TIFFTAG_IMAGEDESCRIPTION, desc);
        const double dz = (z - cz) / rz;
        for (uint32_t y = 0; y < H; ++y) {
            const double dy = (y - cy) / ry;
            for (uint32_t x = 0; x < W; ++x) {
                const double dx = (x - cx) / rx;
                uint16_t v = 0;
                if (dx * dx + dy * dy + dz * dz < 1) {
                    uint32_t h = x * 73856093u ^ y * 19349663u ^ z * 83492791u;  // texture
                    h ^= h >> 13;
                    h *= 0x5bd1e995u;
                    h ^= h >> 15;
                    v = static_cast<uint16_t>(100 + (h & 4095));
                }
                row[x] = v;
            }
            if (TIFFWriteScanline(tif, row.data(), y, 0) != 1) {
                std::fprintf(stderr, "make_tiff_stack: write error on %s\n", out.c_str());
                TIFFClose(tif);
                return 1;
            }
        }
        if (!TIFFWriteDirectory(tif)) {
            std::fprintf(stderr, "make_tiff_stack: write error on %s\n", out.c_str());
            TIFFClose(tif);
            return 1;
        }
    }
    TIFFClose(tif);
    std::printf("make_tiff_stack: %s: %ux%ux%u u16, %.1f MiB of pixels\n", out.c_str(), W, H, D, bytes / 1048576.0);
    return 0;
}

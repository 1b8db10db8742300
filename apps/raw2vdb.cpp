// raw2vdb: converts a dense volume (raw, NRRD, MetaImage, NIfTI-1) or an image stack (a folder holding a
// DICOM series or single-page TIFFs, a multi-page TIFF) into an OpenVDB .vdb file.
// Thin front end over raw_converter.h: parse the command line, one library call, one error line.
// Exit codes: 0 success, 1 bad input or unwritable output, 2 usage error.
#include "cli_numbers.h"
#include "raw_converter.h"
#include "vdb_isosimp/temporary_file.h"

#include <CLI/CLI.hpp>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

using UsageError = vdb_isosimp::CliUsageError;

template <typename T>
std::vector<T> parseList(const std::string& option, const std::string& text, std::size_t n, bool allowX)
{
    return vdb_isosimp::parseNumberList<T>(option, text, n, allowX);
}

// Interrupted (Ctrl-C, kill): remove the temporary output (convertRawToVdb writes OUT.tmp.<pid>) and
// exit at once with 128 + the signal (130 for Ctrl-C, 143 for SIGTERM). unlink, write and _exit are
// async-signal-safe; the output name only ever receives a complete file, by rename.
char gTempPath[4096];

extern "C" void onSignal(int sig)
{
    if (gTempPath[0]) ::unlink(gTempPath);
    static const char msg[] = "raw2vdb: interrupted\n";
    if (::write(STDERR_FILENO, msg, sizeof msg - 1) < 0) {}
    ::_exit(128 + sig);
}

std::string mib(uint64_t bytes)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f MiB", static_cast<double>(bytes) / (1024.0 * 1024.0));
    return buf;
}

} // namespace

int main(int argc, char** argv)
{
    using namespace vdb_isosimp;
    CLI::App app{"raw2vdb: convert a dense volume (raw, NRRD .nrrd/.nhdr, MetaImage .mhd/.mha, NIfTI-1 .nii/.nii.gz) "
                 "or an image stack (a FOLDER of DICOM files of one series or of single-page TIFFs, a multi-page .tif) "
                 "into an OpenVDB float grid (.vdb), streaming slab by slab."};
    std::string input, output, dims, type, endian = "little", spacing, origin, name, gridClass = "fog", clamp, series;
    uint64_t skip = 0;
    double background = 0;
    double tolerance = 0;
    bool half = false, quiet = false;
    app.add_option("input", input, "input volume: a folder (DICOM series or TIFF slices), a .tif/.tiff stack, or a file whose "
                                   "extension names its format (anything else is raw)")->required();
    app.add_option("-o,--output", output, "output .vdb file (written to OUT.tmp.<pid>, renamed on success)")->required();
    app.add_option("--dims", dims, "raw only: sizes X,Y,Z (X fastest)");
    app.add_option("--type", type, "raw only: u8|i8|u16|i16|u32|i32|f32|f64");
    app.add_option("--endian", endian, "raw only: byte order (default little)")->check(CLI::IsMember({"little", "big"}));
    app.add_option("--spacing", spacing, "voxel size SX,SY,SZ (default: the header's or the images', or 1,1,1)");
    app.add_option("--series", series, "DICOM folder with several series: the SeriesInstanceUID to convert");
    app.add_option("--origin", origin, "centre of voxel 0,0,0 OX,OY,OZ (default: the header's, or 0,0,0)");
    app.add_option("--skip", skip, "raw only: bytes to skip before the data (default 0)");
    app.add_option("--name", name, "grid name (default density, or surface for level sets)");
    app.add_option("--class", gridClass, "grid class (default fog)")->check(CLI::IsMember({"fog", "levelset"}));
    auto* backgroundOpt = app.add_option("--background", background, "background value (default 0; level sets: 3 x smallest spacing)");
    app.add_option("--tolerance", tolerance, "merge values within T into tiles / background (default 0, lossless)")
        ->check(CLI::NonNegativeNumber);
    app.add_option("--clamp", clamp, "clamp values (after scaling) to LO,HI");
    app.add_flag("--half", half, "store values as 16-bit half floats");
    app.add_flag("-q,--quiet", quiet, "no progress bar and no summary line");

    RawConvertOptions opt;
    try {
        app.parse(argc, argv);
        if (!dims.empty()) {
            const auto d = parseList<uint64_t>("--dims", dims, 3, true);
            opt.layout.dims = std::array<uint64_t, 3>{{d[0], d[1], d[2]}};
        }
        if (!type.empty()) {
            opt.layout.type = parseScalarType(type);
            if (!opt.layout.type) throw UsageError("--type: unknown type '" + type + "' (u8|i8|u16|i16|u32|i32|f32|f64)");
        }
        if (!spacing.empty()) {
            const auto v = parseList<double>("--spacing", spacing, 3, false);
            opt.spacing = std::array<double, 3>{{v[0], v[1], v[2]}};
        }
        if (!origin.empty()) {
            const auto v = parseList<double>("--origin", origin, 3, false);
            opt.origin = std::array<double, 3>{{v[0], v[1], v[2]}};
        }
        if (!clamp.empty()) {
            const auto v = parseList<double>("--clamp", clamp, 2, false);
            opt.clamp = std::array<double, 2>{{v[0], v[1]}};
        }
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        std::cerr << "raw2vdb: usage: " << e.what() << " (see raw2vdb --help)\n";
        return 2;
    } catch (const UsageError& e) {
        std::cerr << "raw2vdb: usage: " << e.what() << " (see raw2vdb --help)\n";
        return 2;
    }
    opt.layout.byteOrder = endian == "big" ? ByteOrder::Big : ByteOrder::Little;
    opt.layout.skip = skip;
    opt.name = name;
    opt.series = series;
    opt.gridClass = gridClass == "levelset" ? RawGridClass::LevelSet : RawGridClass::Fog;
    if (backgroundOpt->count() > 0) opt.background = background;
    opt.tolerance = tolerance;
    opt.half = half;

    const bool bar = !quiet && ::isatty(STDERR_FILENO);
    auto lastDraw = std::chrono::steady_clock::now() - std::chrono::seconds(1);
    if (bar) {
        opt.progress = [&](uint64_t done, uint64_t total) {
            const auto now = std::chrono::steady_clock::now();
            if (done < total && now - lastDraw < std::chrono::milliseconds(100)) return;
            lastDraw = now;
            const int width = 40;
            const int fill = static_cast<int>(width * done / std::max<uint64_t>(total, 1));
            std::fprintf(stderr, "\rraw2vdb: [%s%s] %3d%%  slab %llu/%llu%s", std::string(fill, '#').c_str(),
                         std::string(width - fill, '-').c_str(), static_cast<int>(100 * done / std::max<uint64_t>(total, 1)),
                         static_cast<unsigned long long>(done), static_cast<unsigned long long>(total),
                         done == total ? "  writing..." : "");
            std::fflush(stderr);
        };
    }

    const std::string tempPath = vdb_isosimp::temporaryPathFor(output);
    if (tempPath.size() < sizeof gTempPath) {
        std::memcpy(gTempPath, tempPath.c_str(), tempPath.size() + 1);
        for (int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, onSignal);
    }
    try {
        const RawConvertStats s = convertRawToVdb(input, output, opt);
        if (bar) std::fprintf(stderr, "\r\033[K");
        if (!quiet) {
            const auto& d = s.info.dims;
            std::string what;
            if (s.source.empty()) {
                what = std::string(formatName(s.info.format)) + ", " + encodingName(s.info.encoding) + " encoding";
            } else {
                char voxel[96];
                std::snprintf(voxel, sizeof voxel, ", voxel %gx%gx%g", s.info.spacing[0], s.info.spacing[1], s.info.spacing[2]);
                what = s.source + voxel;
            }
            std::printf("raw2vdb: %s -> %s: %llux%llux%llu %s (%s), %llu active voxels, %llu leaves, %llu tiles, %.2f s, peak %s\n",
                        input.c_str(), output.c_str(), static_cast<unsigned long long>(d[0]), static_cast<unsigned long long>(d[1]),
                        static_cast<unsigned long long>(d[2]), scalarName(s.info.type), what.c_str(), static_cast<unsigned long long>(s.activeVoxels),
                        static_cast<unsigned long long>(s.leafCount), static_cast<unsigned long long>(s.tileCount), s.seconds,
                        mib(s.peakRssBytes).c_str());
        }
    } catch (const RawInputError& e) {
        if (bar) std::fprintf(stderr, "\r\033[K");
        std::cerr << "raw2vdb: " << e.file() << ": " << e.what() << "\n";
        return 1;
    } catch (const std::exception& e) {
        if (bar) std::fprintf(stderr, "\r\033[K");
        std::cerr << "raw2vdb: " << input << ": " << e.what() << "\n";
        return 1;
    }
    return 0;
}

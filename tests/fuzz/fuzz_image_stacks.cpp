// libFuzzer target: the image-stack readers (slice_source.h) end to end on small inputs. The first byte
// picks the input: a multi-page TIFF file, a folder holding the TIFF as one slice, or a folder of up to
// three DICOM files (the rest of the input cut at each "\xff\xfe\xfd\xfc"). Every header is read through
// openSliceSource, and a small enough volume is converted into a grid (every slice decoded by DCMTK or
// libtiff). Only RawInputError may come out.
#include "fuzz_common.h"
#include "raw_converter.h"

#include <cstring>
#include <string>
#include <sys/stat.h>
#include <unistd.h>

namespace {

void clearFolder(const std::string& folder)
{
    for (const char* name : {"IM0", "IM1", "IM2", "slice.tif"}) ::unlink((folder + "/" + name).c_str());
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    if (size < 1) return 0;
    const int kind = data[0] % 3;
    ++data;
    --size;
    const std::string folder = fuzz::dir() + "/stack";
    ::mkdir(folder.c_str(), 0700);
    clearFolder(folder);
    std::string input;
    if (kind == 0) {
        input = fuzz::writeFile("in.tif", data, size);
    } else if (kind == 1) {
        fuzz::writeFile("stack/slice.tif", data, size);
        input = folder;
    } else {
        static const uint8_t sep[4] = {0xff, 0xfe, 0xfd, 0xfc};
        std::size_t start = 0;
        for (int file = 0; file < 3 && start <= size; ++file) {
            std::size_t end = start;
            while (end + 4 <= size && std::memcmp(data + end, sep, 4) != 0) ++end;
            if (end + 4 > size) end = size;
            fuzz::writeFile("stack/IM" + std::to_string(file), data + start, end - start);
            start = end + 4;
        }
        input = folder;
    }
    try {
        vdb_isosimp::RawConvertOptions opt;
        opt.spacing = std::array<double, 3>{{1, 1, 1}};  // DICOM files without PixelSpacing still convert
        const vdb_isosimp::RawVolumeInfo info = vdb_isosimp::resolveVolumeInfo(input, opt);
        if (info.voxelCount() == 0) __builtin_trap();
        if (info.voxelCount() > 64 * 64 * 64) return 0;  // small volumes only
        vdb_isosimp::convertToGrid(input, opt);
    } catch (const vdb_isosimp::RawInputError&) {
    }
    return 0;
}

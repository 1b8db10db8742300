// libFuzzer target: NIfTI-1 headers (.nii single file, .hdr/.img pair, .nii.gz through zlib).
#include "fuzz_common.h"
#include "raw_header.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    const int kind = size > 0 ? data[0] % 3 : 0;
    if (size > 0) { ++data; --size; }
    static const char* names[] = {"in.nii", "in.hdr", "in.nii.gz"};
    if (kind == 1) fuzz::writeFile("in.img", data, size < 256 ? size : 256);
    const std::string path = fuzz::writeFile(names[kind], data, size);
    try {
        const vdb_isosimp::RawVolumeInfo info = vdb_isosimp::readVolumeInfo(path);
        if (info.voxelCount() == 0) __builtin_trap();
    } catch (const vdb_isosimp::RawInputError&) {
    }
    return 0;
}

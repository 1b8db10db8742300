// libFuzzer target: MetaImage headers (.mhd with a data file beside it, .mha with LOCAL data).
#include "fuzz_common.h"
#include "raw_header.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    const bool mha = size > 0 && (data[0] & 1);
    if (size > 0) { ++data; --size; }
    fuzz::writeFile("data.raw", data, size < 64 ? size : 64);
    const std::string path = fuzz::writeFile(mha ? "in.mha" : "in.mhd", data, size);
    try {
        const vdb_isosimp::RawVolumeInfo info = vdb_isosimp::readVolumeInfo(path);
        if (info.voxelCount() == 0) __builtin_trap();
    } catch (const vdb_isosimp::RawInputError&) {
    }
    return 0;
}

// libFuzzer target: NRRD headers (.nrrd attached, .nhdr detached) through readVolumeInfo. Any input
// must end in a RawInputError or a valid description, never a crash, hang or sanitizer report.
#include "fuzz_common.h"
#include "raw_header.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    // First byte: attached or detached header; the detached one may name "data.raw" beside it.
    const bool detached = size > 0 && (data[0] & 1);
    if (size > 0) { ++data; --size; }
    fuzz::writeFile("data.raw", data, size < 64 ? size : 64);
    const std::string path = fuzz::writeFile(detached ? "in.nhdr" : "in.nrrd", data, size);
    try {
        const vdb_isosimp::RawVolumeInfo info = vdb_isosimp::readVolumeInfo(path);
        if (info.voxelCount() == 0 || info.dataBytes() < info.voxelCount()) __builtin_trap();
    } catch (const vdb_isosimp::RawInputError&) {
    }
    return 0;
}

// libFuzzer target: the converter end to end on small inputs: a header (NRRD, MetaImage, NIfTI or
// a raw layout) and its voxels from the fuzzer's bytes, converted into a grid with options also
// taken from the input (level set, tolerance, clamp, half floats), then written as .vdb.
#include "fuzz_common.h"
#include "raw_converter.h"

#include <cstring>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    if (size < 4) return 0;
    const uint8_t kind = data[0] % 4, flags = data[1], tol = data[2], type = data[3];
    data += 4;
    size -= 4;
    vdb_isosimp::RawConvertOptions opt;
    opt.gridClass = (flags & 1) ? vdb_isosimp::RawGridClass::LevelSet : vdb_isosimp::RawGridClass::Fog;
    opt.tolerance = tol / 64.0;
    if (flags & 2) opt.clamp = std::array<double, 2>{{-double(tol), double(tol)}};
    opt.half = (flags & 4) != 0;
    opt.readAhead = 1 + (flags >> 6);
    std::string path;
    static const char* names[] = {"in.raw", "in.nrrd", "in.mha", "in.nii"};
    if (kind == 0) {
        // Raw: dims from the next three bytes (1..16 each), type from `type`.
        if (size < 3) return 0;
        opt.layout.dims = std::array<uint64_t, 3>{{uint64_t(data[0] % 16 + 1), uint64_t(data[1] % 16 + 1), uint64_t(data[2] % 16 + 1)}};
        static const char* types[] = {"u8", "i8", "u16", "i16", "u32", "i32", "f32", "f64"};
        opt.layout.type = vdb_isosimp::parseScalarType(types[type % 8]);
        opt.layout.byteOrder = (type & 8) ? vdb_isosimp::ByteOrder::Big : vdb_isosimp::ByteOrder::Little;
        data += 3;
        size -= 3;
    }
    path = fuzz::writeFile(names[kind], data, size);
    try {
        const vdb_isosimp::RawVolumeInfo info = vdb_isosimp::resolveVolumeInfo(path, opt);
        if (info.voxelCount() > 64 * 64 * 64 || info.dims[0] > 4096 || info.dims[1] > 4096) return 0;  // small inputs only
        const std::string out = fuzz::dir() + "/out.vdb";
        vdb_isosimp::convertRawToVdb(path, out, opt);
        std::remove(out.c_str());
    } catch (const vdb_isosimp::RawInputError&) {
    }
    return 0;
}

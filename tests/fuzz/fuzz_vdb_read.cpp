// libFuzzer target: the whole .vdb reading path on one input file. Opening (structure and metadata
// checks, OpenVDB's grid listing and topology read with delayed loading, the stored tree's walk),
// the block list, sampling every block (each leaf's first load from the file) with leaves released
// in order as the pipeline does, and the value range (a second delayed-loading read). InputError is
// the only way out; anything else (a crash, a sanitizer report, another exception) is a finding.
// Corpus: tests/fuzz/corpus/vdb_read (the samples of vdb_samples.h).
#include "pipeline/memory_budget.h"
#include "vdb/block_order.h"
#include "vdb/volume_reader.h"
#include "vdb_isosimp/errors.h"

#include "fuzz_common.h"

#include <cstdint>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    const std::string path = fuzz::writeFile("in.vdb", data, size);
    try {
        auto vol = vdb_isosimp::Volume::open(path, "");
        const vdb_isosimp::VolumeInfo& info = vol->info();
        vdb_isosimp::Classifier c;
        c.insideBelow = info.levelSet;
        c.iso = info.levelSet ? 0.0 : 0.5 * (info.background + 1.0);
        // The pipeline's memory check, with a budget that keeps each input to a fraction of a second:
        // a damaged topology's tiles can describe a surface of millions of blocks, a real surface
        // whose meshing would only cost time here.
        vdb_isosimp::checkMemoryBudget(path, info, vdb_isosimp::Options{}, 256ull << 20, vol->tileShellBlocks(c));
        const auto blocks = vol->blocks(c);
        vdb_isosimp::BlockSamples s;
        // Enough blocks for every leaf of a corpus file; a grown input's millions of tile blocks
        // would only cost time.
        const size_t n = std::min<size_t>(blocks.size(), 4096);
        for (size_t i = 0; i < n; ++i) {
            vol->sample(blocks[i], s);
            vol->releaseLeaf(blocks[i]);
        }
        vol->valueRange();
    } catch (const vdb_isosimp::InputError&) {
    }
    return 0;
}

// Faces of the full-resolution surface in each slab of the cut a run makes (the merge tree's slabs,
// pipeline/slabs.h, counted with the face target's own count, pipeline/face_count.h): what a slab's
// seconds follow, so whether slabs of equal blocks are slabs of equal work (docs/scale.md).
// Usage: slab_faces IN.vdb [--iso V] [--slab-blocks N] [--share K]
// Prints one line per slab (index, blocks, faces) and, with --share, the faces of each run of K
// consecutive slabs (a rank's share when slabs / K ranks divide the tree) against their mean.
#include "pipeline/face_count.h"
#include "pipeline/slabs.h"
#include "vdb/volume_reader.h"
#include "vdb_isosimp/errors.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <vector>

int main(int argc, char** argv)
{
    using namespace vdb_isosimp;
    CLI::App app{"slab_faces: full-resolution faces in each slab of the merge tree's cut"};
    std::string input;
    double iso = 0.0;
    uint64_t blocksPerSlab = kDefaultBlocksPerSlab;
    size_t share = 0;
    app.add_option("input", input, "Input .vdb")->required();
    auto* isoOpt = app.add_option("--iso", iso, "Iso-value (default 0; a fog volume needs one)");
    app.add_option("--slab-blocks", blocksPerSlab, "Blocks per slab, as vdb_isosimp's option")->default_val(blocksPerSlab);
    app.add_option("--share", share, "Also sum the faces of each run of this many slabs");
    CLI11_PARSE(app, argc, argv);
    try {
        auto vol = Volume::open(input, "");
        if (!vol->info().levelSet && !*isoOpt) throw InputError(input + ": a fog volume needs --iso");
        const Classifier cls{iso, vol->info().levelSet};
        std::vector<BlockOrigin> blocks = vol->blocks(cls);
        const size_t count = std::min(slabCount(blocks.size(), blocksPerSlab), blocks.size());
        arrangeBlocks(blocks, count);
        const std::vector<Slab> slabs = splitSlabs(blocks, count);
        vol->keepLeaves({});
        const CountRuns all = countRuns(slabs, 0);
        std::vector<uint64_t> faces;
        for (size_t s = 0; s < slabs.size(); ++s) {
            faces.push_back(countFaces(*vol, blocks, all, slabs[s].begin, slabs[s].end, cls, [](double) { return true; }).faces);
            std::printf("%zu %zu %llu\n", s, slabs[s].end - slabs[s].begin, (unsigned long long)faces.back());
        }
        if (share > 0 && faces.size() >= share) {
            std::vector<double> sums;
            for (size_t s = 0; s + share <= faces.size(); s += share) {
                uint64_t sum = 0;
                for (size_t k = s; k < s + share; ++k) sum += faces[k];
                sums.push_back(double(sum));
            }
            double mean = 0.0;
            for (double v : sums) mean += v / double(sums.size());
            const auto most = std::max_element(sums.begin(), sums.end());
            std::printf("shares of %zu slabs: %zu, the largest [%zu, %zu) %.0f faces, %.3f times the mean\n", share,
                        sums.size(), size_t(most - sums.begin()) * share, size_t(most - sums.begin() + 1) * share, *most,
                        mean > 0 ? *most / mean : 0.0);
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "slab_faces: %s\n", e.what());
        return 1;
    }
    return 0;
}

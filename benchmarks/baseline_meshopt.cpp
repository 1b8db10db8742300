// Full extraction, then meshoptimizer's meshopt_simplify (an edge-collapse simplifier with quadric
// error, tuned for speed, common in game/real-time asset pipelines). The extraction is OpenVDB's
// volumeToMesh by default (what an OpenVDB user has at hand) or our pipeline at R = 1.
// Prints one JSON line (as baseline_openmesh) and writes the mesh with -o.
#include "bench_util.h"
#include "pipeline/run_stats.h"
#include "vdb_extract.h"
#include "vdb_isosimp/mesh_writer.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <CLI/CLI.hpp>
#include <meshoptimizer.h>

#include <cfloat>
#include <cmath>
#include <iostream>

using namespace vdb_isosimp;

int main(int argc, char** argv)
{
    CLI::App app{"baseline_meshopt: full extraction + meshoptimizer's meshopt_simplify, for benchmarks"};
    std::string input, output, gridName, extract = "openvdb";
    double ratio = 0.2, iso = 0;
    uint64_t faces = 0;
    app.add_option("input", input, "Input .vdb")->required();
    app.add_option("-o,--output", output, "Write the simplified mesh here (.ply)");
    app.add_option("--grid", gridName, "Grid to mesh (default: the first float or double grid)");
    auto* isoOpt = app.add_option("--iso", iso, "Iso-value (default as vdb_isosimp)");
    app.add_option("-r,--ratio", ratio, "Decimation rate")->default_val(ratio);
    app.add_option("-f,--faces", faces, "Target face count (overrides ratio)");
    app.add_option("--extract", extract, "Full extraction: OpenVDB's volumeToMesh or our pipeline at R = 1")
        ->default_val(extract)->check(CLI::IsMember({"openvdb", "ours"}));
    CLI11_PARSE(app, argc, argv);
    try {
        Stopwatch total;
        Mesh full;
        if (extract == "ours") {
            Options o;
            o.ratio = 1.0;
            o.gridName = gridName;
            if (*isoOpt) o.iso = iso;
            full = simplifyFile(input, o).mesh;
        } else {
            openvdb::GridBase::Ptr grid = bench::loadScalarGrid(input, gridName);
            const double isoValue = *isoOpt ? iso : bench::defaultIso(*grid);
            full = bench::meshWithVolumeToMesh(*grid, isoValue, 0.0);
        }
        const double extractSeconds = total.seconds();
        const size_t facesFull = full.triangles.size();
        const size_t target = faces ? faces : size_t(std::llround(ratio * double(facesFull)));

        Stopwatch simp;
        std::vector<unsigned int> indices(3 * facesFull), out(3 * facesFull);
        for (size_t i = 0; i < facesFull; ++i)
            for (int k = 0; k < 3; ++k) indices[3 * i + k] = full.triangles[i][k];
        full.triangles = {};
        float error = 0;
        // No error bound (FLT_MAX): the face target alone decides, as for the other simplifiers.
        const size_t n = meshopt_simplify(out.data(), indices.data(), indices.size(), &full.points[0][0],
                                          full.points.size(), sizeof(full.points[0]), 3 * target, FLT_MAX, 0, &error);
        indices = {};
        // Keep only the referenced points, in their original order.
        Mesh result;
        std::vector<uint32_t> remap(full.points.size(), UINT32_MAX);
        for (size_t i = 0; i < n; ++i) remap[out[i]] = 0;
        for (size_t v = 0; v < remap.size(); ++v)
            if (remap[v] == 0) {
                remap[v] = uint32_t(result.points.size());
                result.points.push_back(full.points[v]);
            }
        for (size_t i = 0; i < n; i += 3) result.triangles.push_back({remap[out[i]], remap[out[i + 1]], remap[out[i + 2]]});
        const double simpSeconds = simp.seconds();
        if (!output.empty()) writeMesh(result, output, "baseline_meshopt");
        std::cout << bench::JsonLine()
                         .str("tool", "meshopt")
                         .str("extract", extract)
                         .count("faces_full", facesFull)
                         .count("faces_target", target)
                         .count("faces_out", result.triangles.size())
                         .num("extract_seconds", extractSeconds)
                         .num("simplify_seconds", simpSeconds)
                         .num("seconds", total.seconds())
                         .num("peak_rss_mb", peakRssMb(), 1)
                         .num("meshopt_relative_error", error, 6)
                         .text()
                  << std::endl;
        return 0;
    } catch (const std::exception& e) {
        std::cerr << "baseline_meshopt: " << e.what() << "\n";
        return 1;
    }
}

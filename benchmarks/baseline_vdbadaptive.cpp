// OpenVDB's adaptive mesher alone: volumeToMesh with the adaptivity threshold found by bisection in
// [0, 1] so that the (triangulated) face count reaches the target within --tolerance. This is the
// "no simplifier at all" route of OpenVDB/Houdini users. Adaptivity merges voxels only inside leaf
// nodes, so strong reductions may be out of reach: then the run at adaptivity 1 is reported.
// Prints one JSON line; "seconds" counts the whole search, "final_run_seconds" the one run at the
// chosen adaptivity (the cost if the threshold were known in advance).
#include "bench_util.h"
#include "pipeline/run_stats.h"
#include "vdb_extract.h"
#include "vdb_isosimp/mesh_writer.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdlib>
#include <iostream>

using namespace vdb_isosimp;

int main(int argc, char** argv)
{
    CLI::App app{"baseline_vdbadaptive: OpenVDB volumeToMesh with adaptivity tuned to a face count"};
    std::string input, output, gridName;
    double ratio = 0.2, iso = 0, tolerance = 0.03;
    uint64_t faces = 0;
    int maxRuns = 16;
    app.add_option("input", input, "Input .vdb")->required();
    app.add_option("-o,--output", output, "Write the mesh here (.ply)");
    app.add_option("--grid", gridName, "Grid to mesh (default: the first float or double grid)");
    auto* isoOpt = app.add_option("--iso", iso, "Iso-value (default as vdb_isosimp)");
    app.add_option("-r,--ratio", ratio, "Faces kept / faces at adaptivity 0")->default_val(ratio);
    app.add_option("-f,--faces", faces, "Target face count (overrides ratio)");
    app.add_option("--tolerance", tolerance, "Accepted relative distance to the target")->default_val(tolerance);
    app.add_option("--max-runs", maxRuns, "volumeToMesh runs at most")->default_val(maxRuns)->check(CLI::Range(2, 64));
    CLI11_PARSE(app, argc, argv);
    try {
        Stopwatch total;
        openvdb::GridBase::Ptr grid = bench::loadScalarGrid(input, gridName);
        const double isoValue = *isoOpt ? iso : bench::defaultIso(*grid);
        const double loadSeconds = total.seconds();

        int runs = 0;
        double runSeconds = 0;
        auto run = [&](double a) {
            Stopwatch s;
            Mesh m = bench::meshWithVolumeToMesh(*grid, isoValue, a);
            runSeconds = s.seconds();
            ++runs;
            return m;
        };
        const size_t facesFull = run(0.0).triangles.size();
        const size_t target = faces ? faces : size_t(std::llround(ratio * double(facesFull)));
        auto off = [&](size_t n) { return std::abs(double(n) - double(target)) / double(target); };

        // Face count falls (not strictly) as adaptivity grows: bisect on it, keep the closest run.
        Mesh best;
        double bestA = 0, bestSeconds = 0;
        auto consider = [&](Mesh&& m, double a) {
            if (best.triangles.empty() || off(m.triangles.size()) < off(best.triangles.size())) {
                best = std::move(m);
                bestA = a;
                bestSeconds = runSeconds;
            }
        };
        double lo = 0.0, hi = 1.0;
        {
            Mesh m = run(hi);
            const bool reachable = m.triangles.size() <= target;
            consider(std::move(m), hi);
            while (reachable && runs < maxRuns && off(best.triangles.size()) > tolerance) {
                const double mid = 0.5 * (lo + hi);
                Mesh mm = run(mid);
                const size_t n = mm.triangles.size();
                consider(std::move(mm), mid);
                (n > target ? lo : hi) = mid;
            }
        }
        // Grid load + the one run at the chosen adaptivity.
        const double finalRun = loadSeconds + bestSeconds;
        if (!output.empty()) writeMesh(best, output, "baseline_vdbadaptive");
        std::cout << bench::JsonLine()
                         .str("tool", "vdbadaptive")
                         .count("faces_full", facesFull)
                         .count("faces_target", target)
                         .count("faces_out", best.triangles.size())
                         .num("adaptivity", bestA, 6)
                         .count("runs", runs)
                         .num("extract_seconds", finalRun)
                         .num("simplify_seconds", 0.0)
                         .num("final_run_seconds", finalRun)
                         .num("seconds", total.seconds())
                         .num("peak_rss_mb", peakRssMb(), 1)
                         .text()
                  << std::endl;
        return 0;
    } catch (const std::exception& e) {
        std::cerr << "baseline_vdbadaptive: " << e.what() << "\n";
        return 1;
    }
}

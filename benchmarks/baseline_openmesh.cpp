// The in-core route the product competes with: extract the full-resolution surface, then decimate it
// with OpenMesh's DecimaterT + ModQuadricT (the paper's "QSlim"). Prints one JSON line with faces,
// seconds per stage and peak RSS, and writes the mesh if -o is given.
#include "mesh_io.h"
#include "pipeline/run_stats.h"
#include "reference_decimate.h"
#include "vdb_isosimp/errors.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>

int main(int argc, char** argv)
{
    CLI::App app{"baseline_openmesh: full extraction + OpenMesh quadric decimation, for benchmarks"};
    std::string input, output;
    double ratio = 0.2, iso = 0;
    uint64_t faces = 0;
    app.add_option("input", input, "Input .vdb")->required();
    app.add_option("-o,--output", output, "Write the decimated mesh here (.ply)");
    auto* isoOpt = app.add_option("--iso", iso, "Iso-value (default as vdb_isosimp)");
    app.add_option("-r,--ratio", ratio, "Decimation rate")->default_val(ratio);
    app.add_option("-f,--faces", faces, "Target face count (overrides ratio)");
    CLI11_PARSE(app, argc, argv);
    try {
        vdb_isosimp::Stopwatch total;
        vdb_isosimp::Options o;
        o.ratio = 1.0;
        if (*isoOpt) o.iso = iso;
        vdb_isosimp::Result full = vdb_isosimp::simplifyFile(input, o);
        const double extractSeconds = total.seconds();
        const uint64_t target = faces ? faces : uint64_t(std::llround(ratio * double(full.mesh.triangles.size())));
        vdb_isosimp::Stopwatch simp;
        const vdb_isosimp::Mesh out = vdb_isosimp::eval::decimateWithOpenMesh(full.mesh, target);
        const double simpSeconds = simp.seconds();
        if (!output.empty()) vdb_isosimp::eval::writeMeshOpenMesh(out, output);
        std::printf("{\"tool\": \"openmesh\", \"faces_full\": %zu, \"faces_out\": %zu, \"extract_seconds\": %.3f, "
                    "\"simplify_seconds\": %.3f, \"seconds\": %.3f, \"peak_rss_mb\": %.1f}\n",
                    full.mesh.triangles.size(), out.triangles.size(), extractSeconds, simpSeconds, total.seconds(),
                    vdb_isosimp::peakRssMb());
        return 0;
    } catch (const std::exception& e) {
        std::cerr << "baseline_openmesh: " << e.what() << "\n";
        return 1;
    }
}

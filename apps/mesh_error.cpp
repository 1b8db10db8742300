// mesh_error: metro-style distance between two triangle meshes (mean, RMS and max of A->B and
// B->A, symmetric Hausdorff distance), in absolute units and in % of A's bounding box diagonal.
#include "cli_parse.h"
#include "json_text.h"
#include "mesh_error.h"
#include "mesh_io.h"

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>

using namespace vdb_isosimp;

namespace {

Mesh load(const std::string& path) {
    Mesh m = eval::readMesh(path);
    if (m.triangles.empty()) throw std::runtime_error("mesh file '" + path + "' contains no triangles");
    return m;
}

void printJsonDirection(const char* name, const eval::DistanceStats& d, double diag, bool comma) {
    std::printf("  \"%s\": {\"mean\": %.9g, \"rms\": %.9g, \"max\": %.9g, "
                "\"mean_pct\": %.9g, \"rms_pct\": %.9g, \"max_pct\": %.9g, "
                "\"samples\": %zu, \"vertex_queries\": %zu}%s\n",
                name, d.mean, d.rms, d.max, 100 * d.mean / diag, 100 * d.rms / diag, 100 * d.max / diag,
                d.samples, d.vertexQueries, comma ? "," : "");
}

void printDirection(const char* name, const eval::DistanceStats& d, double diag) {
    std::printf("%-5s %14.6g %14.6g %14.6g   %10.4g%% %10.4g%% %10.4g%%   %zu\n", name, d.mean, d.rms, d.max,
                100 * d.mean / diag, 100 * d.rms / diag, 100 * d.max / diag, d.samples);
}

} // namespace

int main(int argc, char** argv) {
    CLI::App app{"Metro-style distance between two triangle meshes A and B. Samples points uniformly by\n"
                 "area on each mesh and measures the exact distance to the other surface. Prints mean,\n"
                 "RMS and max for A->B and B->A, in the meshes' units and in % of the bounding box\n"
                 "diagonal of A (both directions use A's diagonal), and the symmetric Hausdorff\n"
                 "distance. The max of each direction also covers every vertex of the source mesh's faces\n"
                 "with area (a closed component of zero area, a point of the level set, carries no surface).\n"
                 "Reads PLY, OBJ, STL and OFF."};
    std::string pathA, pathB;
    size_t samples = 0;
    uint64_t seed = 1;
    bool json = false;
    int threads = 0;
    app.add_option("A", pathA, "First mesh, usually the reference (full-resolution) surface")->required();
    app.add_option("B", pathB, "Second mesh, usually the simplified surface")->required();
    app.add_option("--samples,-n", samples,
                   "Area samples per direction; 0 (default) = max(1,000,000, faces of the source mesh)");
    app.add_option("--seed,-s", seed, "Seed of the sample positions; results are reproducible for a given seed")
        ->capture_default_str();
    app.add_flag("--json", json, "Print one JSON object instead of the table");
    app.add_option("--threads,-j", threads, "Worker threads (0 = all cores); results do not depend on it")
        ->check(CLI::NonNegativeNumber);
    if (const int code = parseCommandLine(app, argc, argv, "mesh_error"); code >= 0) return code;

    try {
        std::unique_ptr<tbb::global_control> limit;
        if (threads > 0)
            limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));

        const auto start = std::chrono::steady_clock::now();
        const Mesh A = load(pathA);
        const Mesh B = load(pathB);
        const eval::SymmetricDistance d = eval::symmetricDistance(A, B, samples, seed);
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        const double diag = d.ab.diagonal;

        if (json) {
            std::printf("{\n  \"a\": %s,\n  \"b\": %s,\n", jsonString(pathA).c_str(), jsonString(pathB).c_str());
            std::printf("  \"a_faces\": %zu,\n  \"b_faces\": %zu,\n  \"a_bbox_diagonal\": %.9g,\n  \"seed\": %llu,\n",
                        A.triangles.size(), B.triangles.size(), diag, static_cast<unsigned long long>(seed));
            printJsonDirection("a_to_b", d.ab, diag, true);
            printJsonDirection("b_to_a", d.ba, diag, true);
            std::printf("  \"hausdorff\": %.9g,\n  \"hausdorff_pct\": %.9g,\n  \"seconds\": %.3f\n}\n", d.hausdorff,
                        100 * d.hausdorff / diag, seconds);
        } else {
            std::printf("A: %s (%zu vertices, %zu faces), bbox diagonal %.6g\n", pathA.c_str(), A.points.size(),
                        A.triangles.size(), diag);
            std::printf("B: %s (%zu vertices, %zu faces)\n", pathB.c_str(), B.points.size(), B.triangles.size());
            std::printf("%-5s %14s %14s %14s   %11s %11s %11s   %s\n", "", "mean", "rms", "max", "mean/diag",
                        "rms/diag", "max/diag", "samples");
            printDirection("A->B", d.ab, diag);
            printDirection("B->A", d.ba, diag);
            std::printf("Hausdorff distance (symmetric): %.6g (%.4g%% of A's bbox diagonal)\n", d.hausdorff,
                        100 * d.hausdorff / diag);
            std::printf("seed %llu, %.2f s\n", static_cast<unsigned long long>(seed), seconds);
        }
    } catch (const std::exception& e) {
        std::cerr << "mesh_error: " << e.what() << "\n";
        return 1;
    }
    return 0;
}

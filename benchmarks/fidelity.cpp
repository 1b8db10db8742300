// fidelity: error of our simplified surface beside in-core decimators of the full surface, on hard
// surfaces (test_volumes.h) and on any .vdb given. Errors are distances from the full-resolution
// (R = 1) surface in % of its bounding-box diagonal: RMS one-sided (full sampled onto simplified, the
// paper's metro setting), Hausdorff symmetric. References at our face count: OpenMesh (DecimaterT +
// ModQuadricT), meshoptimizer (meshopt_simplify) and, when built with CGAL, CGAL's Garland-Heckbert
// edge collapse (plane quadrics, optimal placement). One markdown row per volume, R and B.
#include "mesh_error.h"
#include "mesh_stats.h"
#include "reference_decimate.h"
#include "test_volumes.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <CLI/CLI.hpp>
#include <meshoptimizer.h>

#ifdef VDB_ISOSIMP_HAVE_CGAL
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/GarlandHeckbert_plane_policies.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#endif

#include <openvdb/io/File.h>

#include <algorithm>
#include <cfloat>
#include <cstdio>
#include <iostream>
#include <optional>

using namespace vdb_isosimp;

namespace {

Mesh meshoptSimplify(const Mesh& full, size_t targetFaces)
{
    std::vector<unsigned> indices, out(3 * full.triangles.size());
    for (const auto& t : full.triangles) indices.insert(indices.end(), t.begin(), t.end());
    const size_t n = meshopt_simplify(out.data(), indices.data(), indices.size(), &full.points[0][0], full.points.size(),
                                      sizeof(full.points[0]), 3 * targetFaces, FLT_MAX, 0, nullptr);
    Mesh m;
    m.points = full.points;
    for (size_t i = 0; i < n; i += 3) m.triangles.push_back({out[i], out[i + 1], out[i + 2]});
    return m;
}

#ifdef VDB_ISOSIMP_HAVE_CGAL
Mesh cgalSimplify(const Mesh& full, size_t targetFaces)
{
    using K = CGAL::Simple_cartesian<double>;
    using SM = CGAL::Surface_mesh<K::Point_3>;
    namespace SMS = CGAL::Surface_mesh_simplification;
    SM sm;
    std::vector<SM::Vertex_index> v;
    for (const auto& p : full.points) v.push_back(sm.add_vertex(K::Point_3(p[0], p[1], p[2])));
    for (const auto& t : full.triangles) sm.add_face(v[t[0]], v[t[1]], v[t[2]]);
    // A closed triangle mesh has 3F/2 edges; the predicate counts edges.
    SMS::Count_stop_predicate<SM> stop(3 * targetFaces / 2);
    SMS::GarlandHeckbert_plane_policies<SM, K> gh(sm);
    SMS::edge_collapse(sm, stop, CGAL::parameters::get_cost(gh.get_cost()).get_placement(gh.get_placement()));
    sm.collect_garbage();
    Mesh m;
    for (auto vi : sm.vertices()) {
        const auto& p = sm.point(vi);
        m.points.push_back({float(p.x()), float(p.y()), float(p.z())});
    }
    for (auto f : sm.faces()) {
        std::array<uint32_t, 3> t{};
        int k = 0;
        for (auto vi : sm.vertices_around_face(sm.halfedge(f))) t[size_t(k++)] = uint32_t(vi);
        m.triangles.push_back(t);
    }
    return m;
}
#endif

struct Cell {
    size_t faces = 0;
    eval::SurfaceError e;
};

std::string cell(const std::optional<Cell>& c)
{
    if (!c) return "— | — | —";
    char b[96];
    std::snprintf(b, sizeof b, "%zu | %.4f | %.4f", c->faces, c->e.rmsPct, c->e.hausdorffPct);
    return b;
}

} // namespace

int main(int argc, char** argv)
{
    CLI::App app{"fidelity: ours beside OpenMesh, meshoptimizer and CGAL on hard surfaces and given volumes"};
    int size = 96;
    std::vector<std::string> names = volumes::hardSurfaceNames(), files;
    std::vector<double> ratios{0.5, 0.2, 0.05};
    std::vector<uint64_t> batches{1000, Options{}.batchFaces};
    bool rotated = true, withCgal = true;
    size_t samples = 0;
    app.add_option("-n,--size", size, "Size of the generated volumes, in voxels")->default_val(size);
    app.add_option("--volumes", names, "Generated volumes (test_volumes.h); 'none' for files only");
    app.add_option("--file", files, "Also these .vdb files: PATH (default grid and iso-value) or PATH:ISO");
    app.add_option("-r,--ratios", ratios, "Decimation rates")->default_val(ratios);
    app.add_option("-b,--batches", batches, "Batch sizes B")->default_val(batches);
    app.add_option("--rotated", rotated, "Also each generated volume under a rotated, anisotropic transform")->default_val(rotated);
    app.add_option("--cgal", withCgal, "Run CGAL's Garland-Heckbert decimator too (when built with CGAL)")->default_val(withCgal);
    app.add_option("--samples", samples, "Area samples per direction (0: max(1M, faces))")->default_val(samples);
    CLI11_PARSE(app, argc, argv);
    try {
        openvdb::initialize();
        struct Input {
            std::string name;
            openvdb::GridBase::Ptr grid;
            std::optional<double> iso;
        };
        std::vector<Input> inputs;
        for (const std::string& n : names) {
            if (n == "none") continue;
            for (bool rot : {false, true}) {
                if (rot && !rotated) continue;
                const volumes::TestVolume v = volumes::makeVolume(n, size, rot);
                inputs.push_back({v.grid->getName(), v.grid, v.iso});
            }
        }
        for (std::string f : files) {
            std::optional<double> iso;
            if (const size_t colon = f.rfind(':'); colon != std::string::npos) {
                iso = std::stod(f.substr(colon + 1));
                f.resize(colon);
            }
            openvdb::io::File file(f);
            file.open(false);
            openvdb::GridBase::Ptr g;
            for (auto it = file.beginName(); it != file.endName() && !g; ++it) {
                openvdb::GridBase::Ptr c = file.readGrid(it.gridName());
                if (c->isType<openvdb::FloatGrid>() || c->isType<openvdb::DoubleGrid>()) g = c;
            }
            if (!g) throw std::runtime_error(f + ": no float or double grid");
            inputs.push_back({f.substr(f.find_last_of('/') + 1) + (iso ? " iso " + std::to_string(*iso).substr(0, 5) : ""), g, iso});
        }
        std::printf("| volume | full faces | R | B | ours faces | ours RMS | ours Hausdorff | OpenMesh faces | RMS | Hausdorff "
                    "| meshopt faces | RMS | Hausdorff | CGAL faces | RMS | Hausdorff | zero-area | closed |\n");
        std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
        for (const Input& in : inputs) {
            Options o;
            o.ratio = 1.0;
            o.iso = in.iso;
            const Mesh full = simplifyGrid(*in.grid, o).mesh;
            for (double r : ratios)
                for (uint64_t b : batches) {
                    o.ratio = r;
                    o.batchFaces = b;
                    const Mesh ours = simplifyGrid(*in.grid, o).mesh;
                    const size_t target = ours.triangles.size();
                    auto measure = [&](const Mesh& m) { return Cell{m.triangles.size(), eval::surfaceError(full, m, samples)}; };
                    // Zero area: below 1e-12 of the squared diagonal.
                    const double diagonal = eval::computeMeshStats(ours).bboxDiagonal;
                    const eval::MeshStats st = eval::computeMeshStats(ours, 1e-12 * diagonal * diagonal);
                    std::optional<Cell> om = measure(eval::decimateWithOpenMesh(full, target));
                    std::optional<Cell> mo = measure(meshoptSimplify(full, target)), cg;
#ifdef VDB_ISOSIMP_HAVE_CGAL
                    if (withCgal) cg = measure(cgalSimplify(full, target));
#endif
                    std::printf("| %s | %zu | %g | %llu | %s | %s | %s | %s | %zu | %s |\n", in.name.c_str(), full.triangles.size(), r,
                                (unsigned long long)b, cell(measure(ours)).c_str(), cell(om).c_str(), cell(mo).c_str(),
                                cell(cg).c_str(), size_t(st.zeroAreaFaces),
                                st.closed() && st.manifold() && st.oriented() && st.signedVolume > 0 ? "yes" : "NO");
                    std::fflush(stdout);
                }
        }
        return 0;
    } catch (const std::exception& e) {
        std::cerr << "fidelity: " << e.what() << "\n";
        return 1;
    }
}

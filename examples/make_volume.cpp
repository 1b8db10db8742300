// make_volume: deterministic test volumes for demos, tests and benchmarks.
//   sphere / torus   narrow-band level sets (openvdb::tools)
//   noise            CT-like fog: fractal value noise, many components, constant regions pruned to tiles
//   gyroid           a fog volume whose surface fills the box
//   gyroid-band      narrow-band level set of the gyroid clipped to a box (closed surface); built leaf by leaf
//                    in parallel, so 1024^3 and more take seconds (the scale run: >= 200M faces at full resolution)
#include "test_volumes.h"

#include <CLI/CLI.hpp>

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <openvdb/tools/ValueTransformer.h>
#include <openvdb/math/Maps.h>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <vector>

namespace {

// Narrow-band (3 voxels) level set of the gyroid sin(xs)cos(ys)+sin(ys)cos(zs)+sin(zs)cos(xs) = 0, s = 2 pi / period,
// intersected with the cube [3.5, size-4.5]^3 so the surface is closed: d = max(gyroid, box), negative inside.
// The gyroid's distance is approximated by f / |grad f| (exact to first order at the surface). Every 8^3 leaf of
// the domain is computed independently (tbb, one leaf list per thread); leaves without a voxel in the band are
// never allocated, and signedFloodFill turns the inside into negative tiles.
openvdb::FloatGrid::Ptr gyroidBand(int size, double period, double voxel)
{
    using LeafT = openvdb::FloatTree::LeafNodeType;
    const double band = 3.0;  // in voxels
    const float background = float(band * voxel);
    const double s = 2 * M_PI / period;
    std::vector<double> sn(static_cast<size_t>(size)), cs(static_cast<size_t>(size));
    for (int i = 0; i < size; ++i) {
        sn[size_t(i)] = std::sin(i * s);
        cs[size_t(i)] = std::cos(i * s);
    }
    const double c = 0.5 * (size - 1), h = 0.5 * (size - 8);  // box centre (voxel centres 0..size-1) and half side
    const int leaves = (size + 7) / 8;                   // leaves per axis
    tbb::enumerable_thread_specific<std::vector<LeafT*>> made;
    tbb::parallel_for(tbb::blocked_range<int>(0, leaves * leaves), [&](const tbb::blocked_range<int>& r) {
        std::vector<LeafT*>& out = made.local();
        float value[LeafT::SIZE];
        bool on[LeafT::SIZE];
        for (int row = r.begin(); row < r.end(); ++row) {
            const int x0 = (row / leaves) * 8, y0 = (row % leaves) * 8;
            for (int z0 = 0; z0 < size; z0 += 8) {
                bool any = false;
                // LeafNode offset: (x & 7) << 6 | (y & 7) << 3 | (z & 7), i.e. z fastest.
                for (int i = 0, n = 0; i < 8; ++i)
                    for (int j = 0; j < 8; ++j)
                        for (int k = 0; k < 8; ++k, ++n) {
                            const int x = x0 + i, y = y0 + j, z = z0 + k;
                            on[n] = false;
                            if (x >= size || y >= size || z >= size) continue;
                            const double sx = sn[size_t(x)], sy = sn[size_t(y)], sz = sn[size_t(z)];
                            const double cx = cs[size_t(x)], cy = cs[size_t(y)], cz = cs[size_t(z)];
                            const double f = sx * cy + sy * cz + sz * cx;
                            const double gx = s * (cx * cy - sz * sx), gy = s * (cy * cz - sx * sy),
                                         gz = s * (cz * cx - sy * sz);
                            const double gl = std::sqrt(gx * gx + gy * gy + gz * gz);
                            const double dg = gl > 1e-12 ? f / gl : std::copysign(1e30, f);
                            const double qx = std::abs(x - c) - h, qy = std::abs(y - c) - h, qz = std::abs(z - c) - h;
                            const double ox = std::max(qx, 0.0), oy = std::max(qy, 0.0), oz = std::max(qz, 0.0);
                            const double db =
                                std::sqrt(ox * ox + oy * oy + oz * oz) + std::min(std::max({qx, qy, qz}), 0.0);
                            const double d = std::max(dg, db);
                            if (std::abs(d) < band) {
                                value[n] = float(d * voxel);
                                on[n] = any = true;
                            }
                        }
                if (!any) continue;
                auto* leaf = new LeafT(openvdb::Coord(x0, y0, z0), background, false);
                for (openvdb::Index n = 0; n < LeafT::SIZE; ++n)
                    if (on[n]) leaf->setValueOn(n, value[n]);
                out.push_back(leaf);
            }
        }
    });
    auto g = openvdb::FloatGrid::create(background);
    g->setGridClass(openvdb::GRID_LEVEL_SET);
    g->setTransform(openvdb::math::Transform::createLinearTransform(voxel));
    for (auto& list : made)
        for (LeafT* leaf : list) g->tree().addLeaf(leaf);  // the tree takes ownership
    openvdb::tools::signedFloodFill(g->tree());
    return g;
}

} // namespace

int main(int argc, char** argv)
{
    CLI::App app{"make_volume: write a deterministic test volume (.vdb)"};
    std::string kind, output;
    int size = 96;
    uint64_t seed = 1;
    double voxel = 1.0, period = 32.0;
    std::vector<std::string> kinds{"sphere", "torus", "noise", "gyroid", "gyroid-band"};
    for (const std::string& v : vdb_isosimp::volumes::volumeNames()) kinds.push_back(v);
    std::string kindList;
    for (const std::string& k : kinds) kindList += (kindList.empty() ? "" : " | ") + k;
    bool rotated = false;
    app.add_option("kind", kind, kindList + "\n(box .. fog-box: hard surfaces of test_volumes.h, ct-int: integers, iso 100)")
        ->required()
        ->check(CLI::IsMember(kinds));
    app.add_option("-o,--output", output, "Output .vdb file")->required();
    app.add_option("-n,--size", size, "Volume size in voxels per axis")->default_val(size)->check(CLI::Range(8, 4096));
    app.add_option("--seed", seed, "Noise seed")->default_val(seed);
    app.add_option("--voxel", voxel, "Voxel size in world units (hard surfaces: a scale on their own transform)")
        ->default_val(voxel)
        ->check(CLI::PositiveNumber);
    app.add_option("--period", period, "Gyroid period in voxels (gyroid, gyroid-band)")
        ->default_val(period)
        ->check(CLI::Range(4.0, 1e6));
    app.add_flag("--rotated", rotated, "Hard surfaces and ct-int: a rotated, anisotropic transform (test_volumes.h)");
    CLI11_PARSE(app, argc, argv);

    openvdb::initialize();
    openvdb::GridBase::Ptr out;
    const double n = size;
    const auto& named = vdb_isosimp::volumes::volumeNames();
    if (std::find(named.begin(), named.end(), kind) != named.end()) {
        openvdb::FloatGrid::Ptr g = vdb_isosimp::volumes::makeVolume(kind, size, rotated).grid;
        if (voxel != 1.0) {
            // The same voxels under a scaled transform; a level set's values are world distances, so
            // they scale with it, a fog's densities do not.
            g->transform().preScale(voxel);
            if (g->getGridClass() == openvdb::GRID_LEVEL_SET) {
                openvdb::tools::foreach(g->beginValueAll(), [voxel](const openvdb::FloatGrid::ValueAllIter& it) {
                    it.setValue(float(double(*it) * voxel));
                });
                // Every tile and voxel, active or not, is scaled above: only the root's own value is left.
                g->tree().root().setBackground(float(double(g->background()) * voxel), /*updateChildNodes=*/false);
            }
        }
        out = g;
    } else if (kind == "sphere") {
        auto g = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(float(0.4 * n * voxel),
                                                                          openvdb::Vec3f(float(0.5 * n * voxel)), float(voxel));
        out = g;
    } else if (kind == "torus") {
        // Narrow band (3 voxels) signed distance to a torus, written directly.
        auto g = openvdb::FloatGrid::create(float(3 * voxel));
        g->setGridClass(openvdb::GRID_LEVEL_SET);
        g->setTransform(openvdb::math::Transform::createLinearTransform(voxel));
        auto acc = g->getAccessor();
        const double R = 0.3 * n, r = 0.1 * n, c = 0.5 * n;
        for (int z = 0; z < size; ++z)
            for (int y = 0; y < size; ++y)
                for (int x = 0; x < size; ++x) {
                    const double dx = x - c, dy = y - c, dz = z - c;
                    const double q = std::sqrt(dx * dx + dy * dy) - R;
                    const double d = (std::sqrt(q * q + dz * dz) - r) * voxel;
                    if (std::abs(d) < 3 * voxel) acc.setValue(openvdb::Coord(x, y, z), float(d));
                }
        openvdb::tools::signedFloodFill(g->tree());
        out = g;
    } else if (kind == "gyroid-band") {
        out = gyroidBand(size, period, voxel);
    } else if (kind == "noise") {
        out = vdb_isosimp::volumes::noiseFog(size, seed, voxel);
    } else {
        const double s = 2 * M_PI / period;
        out = vdb_isosimp::volumes::fog(size, voxel, [&](int x, int y, int z) {
            return 0.5 + 0.5 * (std::sin(x * s) * std::cos(y * s) + std::sin(y * s) * std::cos(z * s) +
                                std::sin(z * s) * std::cos(x * s)) / 1.5;
        });
    }
    if (out->getName().empty()) out->setName(kind);
    openvdb::io::File file(output);
    file.write({out});
    std::cout << "wrote " << output << " (" << kind << ", " << size << "^3";
    if (kind == "gyroid-band")
        std::cout << ", period " << period << ", " << out->activeVoxelCount() << " active voxels, " << out->memUsage()
                  << " bytes in memory";
    std::cout << ")\n";
    return 0;
}

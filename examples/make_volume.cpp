// make_volume: deterministic test volumes for demos, tests and benchmarks.
//   sphere / torus   narrow-band level sets (openvdb::tools)
//   noise            CT-like fog: fractal value noise, many components, constant regions pruned to tiles
//   gyroid           a fog volume whose surface fills the box
//   gyroid-band      narrow-band level set of the gyroid clipped to a box (closed surface); built leaf by leaf
//                    in parallel, so 1024^3 and more take seconds (the scale run: >= 200M faces at full resolution)
#include <CLI/CLI.hpp>

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <openvdb/tools/Prune.h>
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

// Integer hash -> [0,1): deterministic on every platform.
double latticeValue(int64_t x, int64_t y, int64_t z, uint64_t seed)
{
    uint64_t h = seed * 0x9E3779B97F4A7C15ull;
    h ^= uint64_t(x) * 0xBF58476D1CE4E5B9ull;
    h = (h ^ (h >> 31)) * 0x94D049BB133111EBull;
    h ^= uint64_t(y) * 0xD6E8FEB86659FD93ull;
    h = (h ^ (h >> 29)) * 0xBF58476D1CE4E5B9ull;
    h ^= uint64_t(z) * 0x9E3779B97F4A7C15ull;
    h = (h ^ (h >> 32)) * 0x94D049BB133111EBull;
    return double(h >> 11) * (1.0 / 9007199254740992.0);
}

double valueNoise(double x, double y, double z, uint64_t seed)
{
    const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
    const double tx = x - fx, ty = y - fy, tz = z - fz;
    auto s = [](double t) { return t * t * (3 - 2 * t); };
    const double u = s(tx), v = s(ty), w = s(tz);
    const int64_t ix = int64_t(fx), iy = int64_t(fy), iz = int64_t(fz);
    double c[2][2][2];
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < 2; ++j)
            for (int i = 0; i < 2; ++i) c[k][j][i] = latticeValue(ix + i, iy + j, iz + k, seed);
    auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
    return lerp(lerp(lerp(c[0][0][0], c[0][0][1], u), lerp(c[0][1][0], c[0][1][1], u), v),
                lerp(lerp(c[1][0][0], c[1][0][1], u), lerp(c[1][1][0], c[1][1][1], u), v), w);
}

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
    app.add_option("kind", kind, "sphere | torus | noise | gyroid | gyroid-band")
        ->required()
        ->check(CLI::IsMember({"sphere", "torus", "noise", "gyroid", "gyroid-band"}));
    app.add_option("-o,--output", output, "Output .vdb file")->required();
    app.add_option("-n,--size", size, "Volume size in voxels per axis")->default_val(size)->check(CLI::Range(8, 4096));
    app.add_option("--seed", seed, "Noise seed")->default_val(seed);
    app.add_option("--voxel", voxel, "Voxel size in world units")->default_val(voxel);
    app.add_option("--period", period, "Gyroid period in voxels (gyroid, gyroid-band)")
        ->default_val(period)
        ->check(CLI::Range(4.0, 1e6));
    CLI11_PARSE(app, argc, argv);

    openvdb::initialize();
    openvdb::GridBase::Ptr out;
    const double n = size;
    if (kind == "sphere") {
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
    } else {
        auto g = openvdb::FloatGrid::create(0.0f);
        g->setGridClass(openvdb::GRID_FOG_VOLUME);
        g->setTransform(openvdb::math::Transform::createLinearTransform(voxel));
        auto acc = g->getAccessor();
        for (int z = 0; z < size; ++z)
            for (int y = 0; y < size; ++y)
                for (int x = 0; x < size; ++x) {
                    double v;
                    if (kind == "noise") {
                        // Fractal noise, faded to exactly 0 near the border so constant regions become tiles.
                        v = 0;
                        double amp = 0.5, f = 1.0 / 12.0;
                        for (int o = 0; o < 4; ++o, amp *= 0.5, f *= 2) v += amp * valueNoise(x * f, y * f, z * f, seed + o);
                        const double edge = std::min({x, y, z, size - 1 - x, size - 1 - y, size - 1 - z}) / 10.0;
                        v = std::max(0.0, (v - 0.3) * std::min(1.0, edge));
                    } else {
                        const double s = 2 * M_PI / period;
                        v = 0.5 + 0.5 * (std::sin(x * s) * std::cos(y * s) + std::sin(y * s) * std::cos(z * s) +
                                         std::sin(z * s) * std::cos(x * s)) / 1.5;
                    }
                    if (v != 0.0) acc.setValue(openvdb::Coord(x, y, z), float(v));
                }
        openvdb::tools::prune(g->tree());
        out = g;
    }
    out->setName(kind);
    openvdb::io::File file(output);
    file.write({out});
    std::cout << "wrote " << output << " (" << kind << ", " << size << "^3";
    if (kind == "gyroid-band")
        std::cout << ", period " << period << ", " << out->activeVoxelCount() << " active voxels, " << out->memUsage()
                  << " bytes in memory";
    std::cout << ")\n";
    return 0;
}

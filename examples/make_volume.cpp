// make_volume: deterministic test volumes for demos, tests and benchmarks.
//   sphere / torus   narrow-band level sets (openvdb::tools)
//   noise            CT-like fog: fractal value noise, many components, constant regions pruned to tiles
//   gyroid           a fog volume whose surface fills the box
#include <CLI/CLI.hpp>

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <openvdb/tools/Prune.h>
#include <openvdb/math/Maps.h>

#include <cmath>
#include <cstdint>
#include <iostream>

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

} // namespace

int main(int argc, char** argv)
{
    CLI::App app{"make_volume: write a deterministic test volume (.vdb)"};
    std::string kind, output;
    int size = 96;
    uint64_t seed = 1;
    double voxel = 1.0;
    app.add_option("kind", kind, "sphere | torus | noise | gyroid")->required()->check(CLI::IsMember({"sphere", "torus", "noise", "gyroid"}));
    app.add_option("-o,--output", output, "Output .vdb file")->required();
    app.add_option("-n,--size", size, "Volume size in voxels per axis")->default_val(size)->check(CLI::Range(8, 4096));
    app.add_option("--seed", seed, "Noise seed")->default_val(seed);
    app.add_option("--voxel", voxel, "Voxel size in world units")->default_val(voxel);
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
                        const double s = 2 * M_PI / 32.0;
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
    std::cout << "wrote " << output << " (" << kind << ", " << size << "^3)\n";
    return 0;
}

#include "test_volumes.h"

#include <openvdb/tools/Composite.h>
#include <openvdb/tools/LevelSetPlatonic.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/Prune.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vdb_isosimp::volumes {

namespace {

using openvdb::Coord;
using openvdb::FloatGrid;
using openvdb::Vec3d;
using openvdb::Vec3f;

constexpr float kHalfWidth = 3.0f;  // narrow band, in voxels (OpenVDB's default)

// Level sets are made in index space (voxel size 1) and keep those values under any transform: the
// zero crossing, and so the surface's shape in index space, stays the same.
openvdb::math::Transform::Ptr unitTransform() { return openvdb::math::Transform::createLinearTransform(1.0); }

FloatGrid::Ptr levelSetBox(const Vec3d& lo, const Vec3d& hi)
{
    return openvdb::tools::createLevelSetBox<FloatGrid>(openvdb::math::BBox<Vec3d>(lo, hi), *unitTransform(), kHalfWidth);
}

// A closed prism of `sides` sides around the z axis, turned into a level set the way polygonal models
// reach a VDB (mesh to volume).
FloatGrid::Ptr levelSetCylinder(const Vec3d& centre, double radius, double height, int sides)
{
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    for (int i = 0; i < sides; ++i) {
        const double a = 2 * M_PI * i / sides;
        const double x = centre.x() + radius * std::cos(a), y = centre.y() + radius * std::sin(a);
        points.emplace_back(float(x), float(y), float(centre.z() - height / 2));
        points.emplace_back(float(x), float(y), float(centre.z() + height / 2));
    }
    const auto n = openvdb::Index32(points.size());
    points.emplace_back(float(centre.x()), float(centre.y()), float(centre.z() - height / 2));
    points.emplace_back(float(centre.x()), float(centre.y()), float(centre.z() + height / 2));
    for (int i = 0; i < sides; ++i) {
        const auto a = openvdb::Index32(2 * i), b = openvdb::Index32(2 * ((i + 1) % sides));
        quads.emplace_back(a, b, b + 1, a + 1);
        triangles.emplace_back(n, b, a);
        triangles.emplace_back(n + 1, a + 1, b + 1);
    }
    return openvdb::tools::meshToLevelSet<FloatGrid>(*unitTransform(), points, triangles, quads, kHalfWidth);
}

openvdb::math::Transform::Ptr rotatedAnisotropic()
{
    const openvdb::Mat3d rotation = openvdb::math::rotation<openvdb::Mat3d>(Vec3d(1, 2, 3).unit(), 0.5);
    const openvdb::Mat3d scale(1.0, 0.0, 0.0, 0.0, 0.7, 0.0, 0.0, 0.0, 1.3);
    openvdb::Mat4d m = openvdb::Mat4d::identity();
    m.setMat3(scale * rotation);
    m.setTranslation(Vec3d(5.5, -3.25, 2.125));
    return openvdb::math::Transform::createLinearTransform(m);
}

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

double fractalNoise(int x, int y, int z, int size, uint64_t seed)
{
    double v = 0, amp = 0.5, f = 1.0 / 12.0;
    for (int o = 0; o < 4; ++o, amp *= 0.5, f *= 2) v += amp * valueNoise(x * f, y * f, z * f, seed + uint64_t(o));
    const double edge = std::min({x, y, z, size - 1 - x, size - 1 - y, size - 1 - z}) / 10.0;
    return std::max(0.0, (v - 0.3) * std::min(1.0, edge));
}

openvdb::FloatGrid::Ptr fog(int size, double voxel, const std::function<double(int, int, int)>& value)
{
    auto g = openvdb::FloatGrid::create(0.0f);
    g->setGridClass(openvdb::GRID_FOG_VOLUME);
    g->setTransform(openvdb::math::Transform::createLinearTransform(voxel));
    auto acc = g->getAccessor();
    for (int z = 0; z < size; ++z)
        for (int y = 0; y < size; ++y)
            for (int x = 0; x < size; ++x)
                if (const double v = value(x, y, z); v != 0.0) acc.setValue(openvdb::Coord(x, y, z), float(v));
    openvdb::tools::prune(g->tree());
    return g;
}

openvdb::FloatGrid::Ptr noiseFog(int size, uint64_t seed, double voxel)
{
    return fog(size, voxel, [&](int x, int y, int z) { return fractalNoise(x, y, z, size, seed); });
}

const std::vector<std::string>& volumeNames()
{
    static const std::vector<std::string> names = [] {
        std::vector<std::string> n = hardSurfaceNames();
        n.push_back("ct-int");
        return n;
    }();
    return names;
}

const std::vector<std::string>& hardSurfaceNames()
{
    static const std::vector<std::string> names{"box", "cube", "tetrahedron", "octahedron", "dodecahedron",
                                                "icosahedron", "csg", "fog-box"};
    return names;
}

TestVolume makeVolume(const std::string& name, int size, bool rotated)
{
    openvdb::initialize();
    TestVolume out;
    const double n = size;
    // Off the voxel lattice, so most crossings are in general position.
    const Vec3f centre(0.31f, 0.17f, 0.23f);
    const int faces = name == "tetrahedron" ? 4 : name == "cube" ? 6 : name == "octahedron" ? 8
                    : name == "dodecahedron" ? 12 : name == "icosahedron" ? 20 : 0;
    if (faces) {
        out.grid = openvdb::tools::createLevelSetPlatonic<FloatGrid>(faces, float(0.6 * n), centre, 1.0f, kHalfWidth);
    } else if (name == "box") {
        // Integer bounds: the zero crossing lies on voxel planes (values exactly at the iso-value).
        out.grid = levelSetBox(Vec3d(std::round(-0.4 * n), std::round(-0.3 * n), std::round(-0.25 * n)),
                               Vec3d(std::round(0.4 * n), std::round(0.3 * n), std::round(0.25 * n)));
    } else if (name == "csg") {
        // A VDB boolean of modelled parts: two overlapping boxes, minus a 48-sided cylinder through both.
        out.grid = levelSetBox(Vec3d(-0.4 * n, -0.2 * n, -0.15 * n) + 0.37, Vec3d(0.1 * n, 0.2 * n, 0.15 * n) + 0.37);
        FloatGrid::Ptr second = levelSetBox(Vec3d(-0.05 * n, -0.35 * n, -0.25 * n) + 0.21, Vec3d(0.4 * n, 0.1 * n, 0.05 * n) + 0.21);
        openvdb::tools::csgUnion(*out.grid, *second);
        FloatGrid::Ptr hole = levelSetCylinder(Vec3d(0.02 * n, 0.01 * n, 0.13), 0.12 * n, 0.8 * n, 48);
        openvdb::tools::csgDifference(*out.grid, *hole);
    } else if (name == "fog-box") {
        // Density 1 inside, 0 outside, stored as constant tiles (the box is aligned to 8^3 leaves).
        out.grid = FloatGrid::create(0.0f);
        out.grid->setGridClass(openvdb::GRID_FOG_VOLUME);
        auto leaves = [&](double f) { return std::max(2, int(std::lround(f * n / 8))) * 8 - 1; };
        out.grid->tree().fill(openvdb::CoordBBox(Coord(0), Coord(leaves(0.75), leaves(0.5), leaves(0.6))), 1.0f, true);
        out.iso = 0.5;
    } else if (name == "ct-int") {
        out.grid = FloatGrid::create(0.0f);
        out.grid->setGridClass(openvdb::GRID_FOG_VOLUME);
        auto acc = out.grid->getAccessor();
        for (int z = 0; z < size; ++z)
            for (int y = 0; y < size; ++y)
                for (int x = 0; x < size; ++x) {
                    const double v = std::min(255.0, std::round(400.0 * fractalNoise(x, y, z, size, 7)));
                    if (v != 0.0) acc.setValue(Coord(x, y, z), float(v));
                }
        out.iso = 100.0;
    } else {
        throw std::invalid_argument("unknown test volume '" + name + "'");
    }
    if (out.grid->getGridClass() == openvdb::GRID_LEVEL_SET) out.grid->setTransform(unitTransform());
    if (rotated) out.grid->setTransform(rotatedAnisotropic());
    out.grid->setName(rotated ? name + "-rotated" : name);
    return out;
}

} // namespace vdb_isosimp::volumes

#include "test_grids.h"

#include <openvdb/tools/Dense.h>

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <tuple>

namespace vdb_isosimp::testing {

openvdb::FloatGrid::Ptr randomSparseGrid(const GridSpec& spec)
{
    openvdb::initialize();
    std::mt19937 rng(spec.seed);
    const float bg = spec.levelSet ? 3.0f : 0.0f;
    auto grid = openvdb::FloatGrid::create(bg);
    grid->setGridClass(spec.levelSet ? openvdb::GRID_LEVEL_SET : openvdb::GRID_FOG_VOLUME);
    grid->setName(spec.levelSet ? "ls" : "density");
    // Inside values: level set negative, fog above the iso (0.5 in the tests).
    std::uniform_real_distribution<float> val(spec.levelSet ? -2.0f : 0.0f, spec.levelSet ? 2.0f : 1.0f);
    std::uniform_int_distribution<int> leafPos(-4, 4);
    auto& tree = grid->tree();

    if (spec.bigTile) tree.addTile(2, openvdb::Coord(128, 0, 0), spec.levelSet ? -3.0f : 1.0f, true);
    // 8^3 tiles, inside and outside, some touching leaves.
    for (int i = 0; i < 6; ++i) {
        const openvdb::Coord c(8 * leafPos(rng), 8 * leafPos(rng), 8 * leafPos(rng));
        const bool inside = i % 2 == 0;
        tree.addTile(1, c, spec.levelSet ? (inside ? -1.5f : 1.5f) : (inside ? 0.9f : 0.1f), true);
    }
    // Leaves: a few clusters of adjacent leaves plus scattered ones.
    for (int i = 0; i < 14; ++i) {
        openvdb::Coord o(8 * leafPos(rng), 8 * leafPos(rng), 8 * leafPos(rng));
        const int run = i < 4 ? 3 : 1;
        for (int r = 0; r < run; ++r, o.x() += 8) {
            auto* leaf = tree.touchLeaf(o);
            for (openvdb::Index n = 0; n < openvdb::FloatTree::LeafNodeType::SIZE; ++n) {
                float v = val(rng);
                if (spec.exactIso && n % 37 == 0) v = spec.levelSet ? 0.0f : 0.5f;
                leaf->setValueOn(n, v);
            }
        }
    }
    openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
    if (spec.anisotropic) {
        m.preScale(openvdb::Vec3d(0.5, 1.3, 2.0));
        m.postRotate(openvdb::math::Z_AXIS, 0.3);
        m.postRotate(openvdb::math::X_AXIS, -0.7);
        m.postTranslate(openvdb::Vec3d(10.5, -3.25, 7.0));
    }
    if (spec.mirrored) m.postScale(openvdb::Vec3d(-1, 1, 1));
    grid->setTransform(openvdb::math::Transform::createLinearTransform(m));
    return grid;
}

std::string writeGrid(openvdb::GridBase::Ptr grid, const std::string& name)
{
    const std::string path = ::testing::TempDir() + "/" + name + ".vdb";
    openvdb::io::File f(path);
    f.write({grid});
    f.close();
    return path;
}

Mesh denseMarchingCubes(const openvdb::FloatGrid& grid, double iso)
{
    openvdb::CoordBBox box;
    grid.tree().evalLeafBoundingBox(box);
    for (auto it = grid.tree().cbeginValueAll(); it; ++it) {
        if (it.isVoxelValue()) continue;
        if (*it == grid.background()) continue;  // background tiles are the same as empty space
        openvdb::CoordBBox tb;
        it.getBoundingBox(tb);
        box.expand(tb);
    }
    box.expand(1);
    openvdb::tools::Dense<float> dense(box, grid.background());
    openvdb::tools::copyToDense(grid, dense);
    const bool insideBelow = grid.getGridClass() == openvdb::GRID_LEVEL_SET;
    auto value = [&](int x, int y, int z) { return double(dense.getValue(openvdb::Coord(x, y, z))); };
    auto inside = [&](double v) { return insideBelow ? v < iso : v > iso; };
    const openvdb::math::Transform& xf = grid.transform();
    const bool flip = xf.baseMap()->getAffineMap()->getMat4().det() < 0;

    Mesh mesh;
    std::map<std::tuple<int, int, int, int>, uint32_t> weld;
    const auto& table = mcTable();
    for (int z = box.min().z(); z < box.max().z(); ++z)
        for (int y = box.min().y(); y < box.max().y(); ++y)
            for (int x = box.min().x(); x < box.max().x(); ++x) {
                int mask = 0;
                for (int c = 0; c < 8; ++c)
                    if (inside(value(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1)))) mask |= 1 << c;
                const McCase& mc = table[mask];
                for (int t = 0; t < mc.triangleCount; ++t) {
                    std::array<uint32_t, 3> tri;
                    for (int k = 0; k < 3; ++k) {
                        const int e = mc.triangles[t][k];
                        const int c0 = CubeGeometry::edgeCorner(e, 0), axis = CubeGeometry::edgeAxis(e);
                        const int ex = x + (c0 & 1), ey = y + ((c0 >> 1) & 1), ez = z + ((c0 >> 2) & 1);
                        auto [it, isNew] = weld.emplace(std::make_tuple(ex, ey, ez, axis), uint32_t(mesh.points.size()));
                        if (isNew) {
                            const double v0 = value(ex, ey, ez);
                            const double v1 = value(ex + (axis == 0), ey + (axis == 1), ez + (axis == 2));
                            openvdb::Vec3d p(ex, ey, ez);
                            p[axis] += (iso - v0) / (v1 - v0);
                            const openvdb::Vec3d w = xf.indexToWorld(p);
                            mesh.points.push_back({float(w.x()), float(w.y()), float(w.z())});
                        }
                        tri[k] = it->second;
                    }
                    if (flip) std::swap(tri[1], tri[2]);
                    mesh.triangles.push_back(tri);
                }
            }
    return mesh;
}

} // namespace vdb_isosimp::testing

// Full-resolution extraction with OpenVDB's own mesher (tools::volumeToMesh), for the baselines
// that a Houdini/OpenVDB user would reach for. volumeToMesh is a dual method (one vertex per
// surface voxel, quads across crossing edges), so its surface is close to, not identical with, our
// Marching Cubes surface. Its inside convention matches ours (value < iso for level sets; other
// grid classes get their orientation inverted, i.e. inside is value > iso: VolumeToMesh.h,
// "invertSurfaceOrientation"), but it winds faces clockwise seen from outside; turned here.
#pragma once
#include "vdb_isosimp/mesh.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

namespace vdb_isosimp::bench {

// Reads grid `name` (empty: the first float or double grid) completely.
inline openvdb::GridBase::Ptr loadScalarGrid(const std::string& path, const std::string& name)
{
    openvdb::initialize();
    openvdb::io::File file(path);
    file.open(false);  // no delayed loading: volumeToMesh visits every leaf anyway
    openvdb::GridBase::Ptr grid;
    for (auto it = file.beginName(); it != file.endName(); ++it) {
        if (!name.empty() && it.gridName() != name) continue;
        openvdb::GridBase::Ptr g = file.readGrid(it.gridName());
        if (g->isType<openvdb::FloatGrid>() || g->isType<openvdb::DoubleGrid>()) {
            grid = g;
            break;
        }
    }
    file.close();
    if (!grid) throw std::runtime_error(path + ": no float or double grid" + (name.empty() ? "" : " named '" + name + "'"));
    return grid;
}

// Calls f(typedGrid) for a FloatGrid or DoubleGrid.
template <typename F>
auto withScalarGrid(openvdb::GridBase& g, F&& f)
{
    if (auto* fg = dynamic_cast<openvdb::FloatGrid*>(&g)) return f(*fg);
    return f(dynamic_cast<openvdb::DoubleGrid&>(g));
}

inline bool isLevelSet(const openvdb::GridBase& g) { return g.getGridClass() == openvdb::GRID_LEVEL_SET; }

// vdb_isosimp's default: 0 for level sets, else the midpoint of every stored value (voxels, tiles,
// background), like Volume::valueRange.
inline double defaultIso(openvdb::GridBase& g)
{
    if (isLevelSet(g)) return 0.0;
    return withScalarGrid(g, [](auto& grid) {
        double lo = grid.background(), hi = lo;
        for (auto it = grid.tree().cbeginValueAll(); it; ++it) {
            lo = std::min(lo, double(*it));
            hi = std::max(hi, double(*it));
        }
        return 0.5 * (lo + hi);
    });
}

// One volumeToMesh run; quads split along their 0-2 diagonal, faces turned counter-clockwise from
// outside (also under a mirroring transform).
inline Mesh meshWithVolumeToMesh(const openvdb::GridBase& g, double iso, double adaptivity)
{
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> tris;
    std::vector<openvdb::Vec4I> quads;
    withScalarGrid(const_cast<openvdb::GridBase&>(g), [&](auto& grid) {
        openvdb::tools::volumeToMesh(grid, points, tris, quads, iso, adaptivity);
    });
    const openvdb::math::Transform& xf = g.transform();
    const openvdb::Vec3d o = xf.indexToWorld(openvdb::Vec3d(0, 0, 0));
    const openvdb::Vec3d ex = xf.indexToWorld(openvdb::Vec3d(1, 0, 0)) - o;
    const openvdb::Vec3d ey = xf.indexToWorld(openvdb::Vec3d(0, 1, 0)) - o;
    const openvdb::Vec3d ez = xf.indexToWorld(openvdb::Vec3d(0, 0, 1)) - o;
    const bool mirrored = ex.dot(ey.cross(ez)) < 0;

    Mesh m;
    m.points.resize(points.size());
    for (size_t i = 0; i < points.size(); ++i) m.points[i] = {points[i][0], points[i][1], points[i][2]};
    points = {};
    m.triangles.reserve(tris.size() + 2 * quads.size());
    auto add = [&](uint32_t a, uint32_t b, uint32_t c) {
        if (mirrored) m.triangles.push_back({a, b, c});
        else m.triangles.push_back({a, c, b});
    };
    for (const auto& q : quads) {
        add(q[0], q[1], q[2]);
        add(q[0], q[2], q[3]);
    }
    for (const auto& t : tris) add(t[0], t[1], t[2]);
    return m;
}

} // namespace vdb_isosimp::bench

// upsample_volume: trilinear up-sampling of a float/double grid by an integer factor f, the way the
// paper built its large data sets from small ones (section 5: "bunny*", "head*").
//
// Output voxel j sits at input index j/f, so its value is the trilinear interpolation of the 8 input
// voxels around j/f; the transform is pre-scaled by 1/f, so the surface stays where it was in world
// space. Work goes region by region (one input leaf's 8^3 voxels -> f^3 output leaves) and only where
// the input is not constant: leaves, the leaves' lower neighbours (their last voxel slab interpolates
// towards the leaf) and the shells of tiles. Constant regions become tiles, so memory is about the
// output tree (plus the input grid), never a dense array. The output does not depend on threads.
#include <CLI/CLI.hpp>

#include <openvdb/openvdb.h>
#include <openvdb/tools/Prune.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <iostream>
#include <memory>
#include <tuple>
#include <vector>

namespace {

using openvdb::Coord;
using openvdb::CoordBBox;

Coord scaled(const Coord& c, int f) { return Coord(c.x() * f, c.y() * f, c.z() * f); }

// Candidate regions: origins (multiples of 8) of input 8^3 blocks whose output may not be constant.
template <typename TreeT>
std::vector<Coord> candidateRegions(const TreeT& tree)
{
    std::vector<Coord> regions;
    for (auto leaf = tree.cbeginLeaf(); leaf; ++leaf) {
        const Coord o = leaf->origin();
        for (int k = 0; k < 8; ++k) regions.push_back(o - Coord(k & 1 ? 8 : 0, k & 2 ? 8 : 0, k & 4 ? 8 : 0));
    }
    // Tiles: blocks just outside their min faces and just inside their max faces, where the value
    // may change within one input voxel step. Constant ones are dropped later by a probe.
    // Background tiles need none: where one meets another value, the other side's shells (or its
    // leaves' lower neighbours) cover the step, and background-to-background is constant.
    for (auto it = tree.cbeginValueAll(); it; ++it) {
        if (it.isVoxelValue() || *it == tree.background()) continue;
        const CoordBBox b = it.getBoundingBox();
        for (int axis = 0; axis < 3; ++axis) {
            for (int side = 0; side < 2; ++side) {
                const int32_t a = side == 0 ? b.min()[axis] - 8 : b.max()[axis] - 7;
                const int u = (axis + 1) % 3, v = (axis + 2) % 3;
                for (int32_t p = b.min()[u]; p <= b.max()[u]; p += 8)
                    for (int32_t q = b.min()[v]; q <= b.max()[v]; q += 8) {
                        Coord c;
                        c[axis] = a;
                        c[u] = p;
                        c[v] = q;
                        regions.push_back(c);
                    }
            }
        }
    }
    std::sort(regions.begin(), regions.end(), [](const Coord& a, const Coord& b) {
        return std::make_tuple(a.z(), a.y(), a.x()) < std::make_tuple(b.z(), b.y(), b.x());
    });
    regions.erase(std::unique(regions.begin(), regions.end()), regions.end());
    return regions;
}

template <typename GridT>
typename GridT::Ptr upsample(const GridT& in, int f)
{
    using TreeT = typename GridT::TreeType;
    using LeafT = typename TreeT::LeafNodeType;
    using ValueT = typename GridT::ValueType;
    const TreeT& itree = in.tree();

    auto out = GridT::create(itree.background());
    out->setGridClass(in.getGridClass());
    out->setName(in.getName());
    openvdb::math::Transform::Ptr xform = in.transform().copy();
    xform->preScale(1.0 / f);
    out->setTransform(xform);
    TreeT& otree = out->tree();

    // Tiles first (sparse fill: stays tiles); regions overwrite their borders below.
    for (auto it = itree.cbeginValueAll(); it; ++it) {
        if (it.isVoxelValue() || (*it == itree.background() && !it.isValueOn())) continue;
        const CoordBBox b = it.getBoundingBox();
        otree.sparseFill(CoordBBox(scaled(b.min(), f), scaled(b.max() + Coord(1), f) - Coord(1)), *it, it.isValueOn());
    }

    const std::vector<Coord> regions = candidateRegions(itree);
    const int n = 8 * f;             // output voxels per region and axis
    const size_t chunk = 2048;       // regions per parallel round: bounds the memory held in flight
    uint64_t leaves = 0;
    for (size_t c0 = 0; c0 < regions.size(); c0 += chunk) {
        const size_t c1 = std::min(regions.size(), c0 + chunk);
        std::vector<std::vector<std::unique_ptr<LeafT>>> made(c1 - c0);
        tbb::parallel_for(size_t(c0), c1, [&](size_t r) {
            const Coord o = regions[r];
            typename GridT::ConstAccessor acc(itree);
            // 9^3 input samples: the region and its +x/+y/+z layer.
            std::array<ValueT, 729> val;
            std::array<bool, 729> on;
            bool constant = !acc.probeConstLeaf(o);
            for (int z = 0; z < 9; ++z)
                for (int y = 0; y < 9; ++y)
                    for (int x = 0; x < 9; ++x) {
                        const int i = (z * 9 + y) * 9 + x;
                        on[i] = acc.probeValue(o + Coord(x, y, z), val[i]);
                        constant = constant && val[i] == val[0];
                    }
            if (constant) return;  // already right: a tile fill or the background
            auto& dst = made[r - c0];
            // Per output coordinate (relative): lower input sample and weight, and the nearest sample.
            std::vector<int> lo(n), near(n);
            std::vector<double> w(n);
            for (int j = 0; j < n; ++j) {
                lo[j] = j / f;
                w[j] = double(j % f) / f;
                near[j] = (2 * (j % f) >= f) ? lo[j] + 1 : lo[j];
            }
            for (int bz = 0; bz < f; ++bz)
                for (int by = 0; by < f; ++by)
                    for (int bx = 0; bx < f; ++bx) {
                        const Coord lorigin = scaled(o, f) + Coord(bx * 8, by * 8, bz * 8);
                        auto leaf = std::make_unique<LeafT>(lorigin, itree.background(), false);
                        for (int z = 0; z < 8; ++z)
                            for (int y = 0; y < 8; ++y)
                                for (int x = 0; x < 8; ++x) {
                                    const int jx = bx * 8 + x, jy = by * 8 + y, jz = bz * 8 + z;
                                    const int ix = lo[jx], iy = lo[jy], iz = lo[jz];
                                    const double tx = w[jx], ty = w[jy], tz = w[jz];
                                    auto at = [&](int dx, int dy, int dz) {
                                        return double(val[((iz + dz) * 9 + iy + dy) * 9 + ix + dx]);
                                    };
                                    const double c00 = at(0, 0, 0) + (at(1, 0, 0) - at(0, 0, 0)) * tx;
                                    const double c10 = at(0, 1, 0) + (at(1, 1, 0) - at(0, 1, 0)) * tx;
                                    const double c01 = at(0, 0, 1) + (at(1, 0, 1) - at(0, 0, 1)) * tx;
                                    const double c11 = at(0, 1, 1) + (at(1, 1, 1) - at(0, 1, 1)) * tx;
                                    const double c0 = c00 + (c10 - c00) * ty, c1 = c01 + (c11 - c01) * ty;
                                    const ValueT v = ValueT(c0 + (c1 - c0) * tz);
                                    const bool a = on[(near[jz] * 9 + near[jy]) * 9 + near[jx]];
                                    const openvdb::Index idx = LeafT::coordToOffset(lorigin + Coord(x, y, z));
                                    leaf->setValueOnly(idx, v);
                                    leaf->setActiveState(idx, a);
                                }
                        dst.push_back(std::move(leaf));
                    }
        });
        // Serial, in region order: the tree does not depend on the thread count.
        for (auto& region : made)
            for (auto& leaf : region) {
                // Constant: a leaf-sized tile (level 1) instead of 8^3 voxels.
                ValueT v;
                bool state;
                if (leaf->isConstant(v, state)) {
                    otree.addTile(1, leaf->origin(), v, state);
                    continue;
                }
                otree.addLeaf(leaf.release());
                ++leaves;
            }
    }
    openvdb::tools::prune(otree);
    std::cout << "regions " << regions.size() << ", output leaves " << leaves << "\n";
    return out;
}

} // namespace

int main(int argc, char** argv)
{
    CLI::App app{"upsample_volume: trilinear up-sampling of a float/double grid by an integer factor"};
    std::string input, output, gridName;
    int factor = 2;
    app.add_option("input", input, "Input .vdb")->required()->check(CLI::ExistingFile);
    app.add_option("-o,--output", output, "Output .vdb")->required();
    app.add_option("-f,--factor", factor, "Up-sampling factor per axis")->default_val(factor)->check(CLI::Range(1, 16));
    app.add_option("--grid", gridName, "Grid to up-sample (default: the first float or double grid)");
    CLI11_PARSE(app, argc, argv);

    openvdb::initialize();
    try {
        openvdb::io::File file(input);
        file.open();
        openvdb::GridBase::Ptr base;
        for (auto it = file.beginName(); it != file.endName(); ++it) {
            if (!gridName.empty() && it.gridName() != gridName) continue;
            openvdb::GridBase::Ptr g = file.readGrid(it.gridName());
            if (g->isType<openvdb::FloatGrid>() || g->isType<openvdb::DoubleGrid>()) { base = g; break; }
        }
        file.close();
        if (!base) {
            std::cerr << "upsample_volume: " << input << ": no " << (gridName.empty() ? "float or double grid" : "grid '" + gridName + "' of type float or double") << "\n";
            return 1;
        }
        openvdb::GridBase::Ptr out;
        if (auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(base)) out = upsample(*g, factor);
        else out = upsample(*openvdb::gridPtrCast<openvdb::DoubleGrid>(base), factor);
        openvdb::io::File(output).write({out});
        std::cout << "wrote " << output << " (" << base->getName() << " x" << factor << ")\n";
    } catch (const std::exception& e) {
        std::cerr << "upsample_volume: " << e.what() << "\n";
        return 1;
    }
    return 0;
}

#include "grid_volume.h"

#include "block_order.h"
#include "errors.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace vdb_isosimp {

namespace {

template <typename GridT>
class GridVolume final : public Volume {
public:
    GridVolume(typename GridT::ConstPtr grid, VolumeInfo info) : mGrid(std::move(grid)) { mInfo = std::move(info); }

    std::vector<std::array<int32_t, 3>> blocks(const Classifier& c) const override
    {
        return collectBlocks(mGrid->tree(), c);
    }

    void sample(const std::array<int32_t, 3>& origin, BlockSamples& out) const override
    {
        typename GridT::ConstAccessor acc = mGrid->getConstAccessor();
        out.origin = origin;
        constexpr int N = BlockSamples::N;
        openvdb::Coord ijk;
        for (int z = 0; z < N; ++z) {
            ijk.z() = origin[2] + z;
            for (int y = 0; y < N; ++y) {
                ijk.y() = origin[1] + y;
                for (int x = 0; x < N; ++x) {
                    ijk.x() = origin[0] + x;
                    const double v = double(acc.getValue(ijk));
                    if (!std::isfinite(v)) {
                        std::ostringstream s;
                        s << "voxel " << ijk << " of grid '" << mInfo.gridName << "' is " << v
                          << " (NaN/Inf values are not allowed)";
                        throw InputError(s.str());
                    }
                    out.at(x, y, z) = v;
                }
            }
        }
    }

    void releaseLeaf(const std::array<int32_t, 3>&) override {}  // the caller's grid stays whole

    std::array<double, 2> valueRange() const override
    {
        double lo = double(mGrid->background()), hi = lo;
        for (auto it = mGrid->tree().cbeginValueAll(); it; ++it) {
            const double v = double(*it);
            lo = std::min(lo, v);
            hi = std::max(hi, v);
        }
        return {lo, hi};
    }

private:
    typename GridT::ConstPtr mGrid;
};

// OpenVDB multiplies row vectors: world = index * M, translation in row 3.
Affine affineOf(const openvdb::math::Transform& xform)
{
    const openvdb::Mat4d m = xform.baseMap()->getAffineMap()->getMat4();
    Affine a;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) a.m[size_t(r * 4 + c)] = m(c, r);
        a.m[size_t(r * 4 + 3)] = m(3, r);
    }
    return a;
}

template <typename GridT>
std::unique_ptr<Volume> make(typename GridT::ConstPtr g, VolumeInfo info)
{
    info.background = double(g->background());
    info.leafCount = g->tree().leafCount();
    info.activeVoxels = g->activeVoxelCount();
    if (info.activeVoxels == 0 && info.leafCount == 0)
        throw InputError(info.file + ": grid '" + info.gridName + "' is empty (no active voxels)");
    return std::make_unique<GridVolume<GridT>>(std::move(g), std::move(info));
}

} // namespace

std::unique_ptr<Volume> volumeFromGrid(openvdb::GridBase::ConstPtr grid, const std::string& label)
{
    if (!grid) throw InputError(label + ": no grid");
    const bool isFloat = grid->isType<openvdb::FloatGrid>(), isDouble = grid->isType<openvdb::DoubleGrid>();
    if (!isFloat && !isDouble)
        throw InputError(label + ": grid '" + grid->getName() + "' has value type " + grid->valueType() +
                         "; only float and double grids can be meshed");
    if (!grid->transform().isLinear())
        throw InputError(label + ": grid '" + grid->getName() + "' has a non-linear transform (" +
                         grid->transform().mapType() + "); only linear transforms are supported");
    VolumeInfo info;
    info.file = label;
    info.gridName = grid->getName();
    info.valueType = grid->valueType();
    info.levelSet = grid->getGridClass() == openvdb::GRID_LEVEL_SET;
    info.indexToWorld = affineOf(grid->transform());
    if (std::abs(info.indexToWorld.determinant()) < 1e-300)
        throw InputError(label + ": grid '" + info.gridName + "' has a singular transform");
    if (isFloat) return make<openvdb::FloatGrid>(openvdb::GridBase::constGrid<openvdb::FloatGrid>(grid), info);
    return make<openvdb::DoubleGrid>(openvdb::GridBase::constGrid<openvdb::DoubleGrid>(grid), info);
}

} // namespace vdb_isosimp

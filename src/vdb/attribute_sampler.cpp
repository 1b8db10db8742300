#include "vdb/attribute_sampler.h"

#include "vdb_isosimp/errors.h"

#include <openvdb/io/File.h>
#include <openvdb/tools/Interpolation.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <mutex>

namespace vdb_isosimp {

namespace {

bool numeric(const openvdb::GridBase& g)
{
    return g.isType<openvdb::FloatGrid>() || g.isType<openvdb::DoubleGrid>() || g.isType<openvdb::Vec3SGrid>() ||
           g.isType<openvdb::Vec3DGrid>();
}

// Samples one grid at every point into `out` (`components` floats per point), in parallel: each
// range of points has its own accessor (accessors cache nodes and are not shared between threads).
// The k-th component of a value: the value itself for a scalar.
template <typename T>
float component(const T& v, uint32_t k)
{
    if constexpr (openvdb::VecTraits<T>::IsVec) return float(v[int(k)]);
    else return (void)k, float(v);
}

template <typename GridT>
void sampleGrid(const GridT& grid, const std::vector<std::array<float, 3>>& points, VertexAttribute& out)
{
    using ValueT = typename GridT::ValueType;
    constexpr uint32_t n = openvdb::VecTraits<ValueT>::Size;
    out.components = n;
    out.values.resize(points.size() * n);
    const openvdb::math::Transform& xform = grid.transform();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, points.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
        auto acc = grid.getConstUnsafeAccessor();  // one run of points on a grid read whole: not registered (volume_reader.cpp)
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const openvdb::Vec3d world(points[i][0], points[i][1], points[i][2]);
            const ValueT v = openvdb::tools::BoxSampler::sample(acc, xform.worldToIndex(world));
            for (uint32_t k = 0; k < n; ++k) out.values[i * n + k] = component(v, k);
        }
    });
}

} // namespace

AttributeSampler::AttributeSampler(const std::string& path, const std::vector<std::string>& names)
    : mPath(path), mNames(names)
{
    if (mNames.empty()) return;
    static std::once_flag init;
    std::call_once(init, [] { openvdb::initialize(); });
    openvdb::GridPtrVecPtr metas;
    try {
        openvdb::io::File file(path);
        file.open(/*delayLoad=*/true);
        metas = file.readAllGridMetadata();
        file.close();
    } catch (const std::exception& e) {
        throw InputError(path + ": cannot read its grids for attributes (" + e.what() + ")");
    }
    for (const std::string& name : mNames) {
        openvdb::GridBase::Ptr found;
        for (const auto& g : *metas)
            if (g->getName() == name) found = g;
        if (!found) {
            std::string have;
            for (const auto& g : *metas) have += (have.empty() ? "" : ", ") + ("'" + g->getName() + "'");
            throw InputError(path + ": no grid named '" + name + "' to sample as an attribute (grids: " + have + ")");
        }
        if (!numeric(*found))
            throw InputError(path + ": grid '" + name + "' has value type " + found->valueType() +
                             "; attributes are float, double or vec3 grids");
        if (&name == &mNames.front())
            mFirstScalar = found->isType<openvdb::FloatGrid>() || found->isType<openvdb::DoubleGrid>();
    }
}

void AttributeSampler::load()
{
    if (mNames.empty() || !mGrids.empty()) return;
    try {
        openvdb::io::File file(mPath);
        file.open();
        for (const std::string& name : mNames) mGrids.push_back(file.readGrid(name));
        file.close();
    } catch (const std::exception& e) {
        mGrids.clear();
        throw InputError(mPath + ": cannot read the attribute grids (" + e.what() + ")");
    }
}

void AttributeSampler::sampleFirst(const std::vector<std::array<double, 3>>& points, std::vector<double>& out) const
{
    out.resize(points.size());
    const auto run = [&](const auto& grid) {
        auto acc = grid.getConstUnsafeAccessor();
        const openvdb::math::Transform& xform = grid.transform();
        for (size_t i = 0; i < points.size(); ++i)
            out[i] = double(openvdb::tools::BoxSampler::sample(acc, xform.worldToIndex(openvdb::Vec3d(points[i][0], points[i][1], points[i][2]))));
    };
    const openvdb::GridBase& g = *mGrids.front();
    if (g.isType<openvdb::FloatGrid>()) run(static_cast<const openvdb::FloatGrid&>(g));
    else run(static_cast<const openvdb::DoubleGrid&>(g));
}

std::vector<VertexAttribute> AttributeSampler::sample(const std::vector<std::array<float, 3>>& points) const
{
    std::vector<VertexAttribute> out(mGrids.size());
    for (size_t i = 0; i < mGrids.size(); ++i) {
        const openvdb::GridBase& g = *mGrids[i];
        out[i].name = mNames[i];
        if (g.isType<openvdb::FloatGrid>()) sampleGrid(static_cast<const openvdb::FloatGrid&>(g), points, out[i]);
        else if (g.isType<openvdb::DoubleGrid>()) sampleGrid(static_cast<const openvdb::DoubleGrid&>(g), points, out[i]);
        else if (g.isType<openvdb::Vec3SGrid>()) sampleGrid(static_cast<const openvdb::Vec3SGrid&>(g), points, out[i]);
        else sampleGrid(static_cast<const openvdb::Vec3DGrid&>(g), points, out[i]);
    }
    return out;
}

} // namespace vdb_isosimp

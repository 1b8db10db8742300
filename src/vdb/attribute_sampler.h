// Vertex attributes: other grids of the input file (float, double, vec3) sampled trilinearly at the
// output vertices, each in its own index space (world -> index by the grid's own transform), so grids
// with a different voxel size, offset or rotation than the meshed one sample where the vertex lies.
#pragma once
#include "vdb_isosimp/mesh.h"

#include <openvdb/openvdb.h>

#include <array>
#include <string>
#include <vector>

namespace vdb_isosimp {

class AttributeSampler {
public:
    // Checks that `path` holds every grid of `names` with a numeric value type (float, double, vec3s,
    // vec3d), reading metadata only. @throw InputError naming the file and the grid.
    AttributeSampler(const std::string& path, const std::vector<std::string>& names);

    bool empty() const { return mNames.empty(); }

    // Reads the grids (once; later calls do nothing). @throw InputError naming the file.
    void load();

    // One attribute per grid, in the order of the names given: the grid's value at each point (BoxSampler,
    // trilinear), 1 or 3 floats per point. load() first.
    std::vector<VertexAttribute> sample(const std::vector<std::array<float, 3>>& points) const;

    // Whether the first grid named holds one value per voxel (float or double), from the metadata.
    bool firstIsScalar() const { return mFirstScalar; }

    // The first grid's value at each world point, trilinear, into `out` (resized). Thread-safe; load()
    // first.
    void sampleFirst(const std::vector<std::array<double, 3>>& points, std::vector<double>& out) const;

private:
    bool mFirstScalar = false;
    std::string mPath;
    std::vector<std::string> mNames;
    std::vector<openvdb::GridBase::Ptr> mGrids;
};

} // namespace vdb_isosimp

// The library entry points around simplifyFile(): a grid already in memory, and the streaming
// variants that hand the final mesh to a MeshSink.
//
// simplifyGrid() runs the same pipeline over Volume::fromGrid(), a read-only view of the caller's grid
// (its voxel buffers are never released).
#include "vdb_isosimp/vdb_isosimp.h"

#include "pipeline/pipeline_internal.h"
#include "vdb/volume_reader.h"
#include "vdb_isosimp/errors.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <cstdlib>
#include <mutex>
#include <string>
#include <unistd.h>

namespace vdb_isosimp {

namespace {

bool isScalar(const openvdb::GridBase& g)
{
    return g.isType<openvdb::FloatGrid>() || g.isType<openvdb::DoubleGrid>();
}

// Hands a finished mesh to a sink in pieces, freeing the points before the triangles go out.
void feed(Mesh&& mesh, const Report& report, MeshSink& sink)
{
    constexpr size_t kPiece = 65536;
    sink.begin(report);
    for (size_t i = 0; i < mesh.points.size(); i += kPiece)
        sink.vertices(mesh.points.data() + i, std::min(kPiece, mesh.points.size() - i));
    std::vector<std::array<float, 3>>().swap(mesh.points);
    for (size_t i = 0; i < mesh.triangles.size(); i += kPiece)
        sink.triangles(mesh.triangles.data() + i, std::min(kPiece, mesh.triangles.size() - i));
    std::vector<std::array<uint32_t, 3>>().swap(mesh.triangles);
    for (const VertexAttribute& a : mesh.attributes) sink.attribute(a);
    sink.end();
}

} // namespace

Result simplifyGrid(const openvdb::GridBase& grid, const Options& options, Progress* progress)
{
    static std::once_flag init;
    std::call_once(init, [] { openvdb::initialize(); });

    const std::string label = "in-memory grid '" + grid.getName() + "'";
    if (!isScalar(grid))
        throw InputError(label + ": value type " + grid.valueType() + "; only float and double grids can be meshed");

    if (!options.attributes.empty())
        throw InputError(label + ": attributes are sampled from the other grids of a file; an in-memory grid has none");
    // Read the caller's grid in place: the grid volume never frees voxel buffers.
    openvdb::GridBase::ConstPtr g = grid.copyGrid();  // shares the tree
    Result r = simplifyVolume([&] { return Volume::fromGrid(g, label); }, label, options, progress);
    r.report.file.clear();
    return r;
}

Report simplifyFile(const std::string& vdbPath, const Options& options, MeshSink& sink, Progress* progress)
{
    Result r = simplifyFile(vdbPath, options, progress);
    feed(std::move(r.mesh), r.report, sink);
    return r.report;
}

Report simplifyGrid(const openvdb::GridBase& grid, const Options& options, MeshSink& sink, Progress* progress)
{
    Result r = simplifyGrid(grid, options, progress);
    feed(std::move(r.mesh), r.report, sink);
    return r.report;
}

} // namespace vdb_isosimp

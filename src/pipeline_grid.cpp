// The library entry points around simplifyFile(): a grid already in memory, and the streaming
// variants that hand the final mesh to a MeshSink.
//
// simplifyGrid() hands the grid to the file pipeline through a temporary .vdb holding a shallow copy
// of it (the tree is shared, not copied, while it is written). The pipeline opens its input through
// Volume::open(path), and releases voxel buffers as blocks finish, which a caller's grid must not
// undergo; a direct path needs the pipeline to accept an already-open, read-only volume.
#include "vdb_isosimp.h"

#include "errors.h"

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

// A temporary .vdb removed when it goes out of scope.
class TempVdb {
public:
    TempVdb()
    {
        const char* dir = std::getenv("TMPDIR");
        std::string pattern = std::string(dir && *dir ? dir : "/tmp") + "/vdb_isosimp_grid_XXXXXX.vdb";
        const int fd = ::mkstemps(pattern.data(), 4);
        if (fd < 0) throw InputError("cannot create a temporary file in " + pattern.substr(0, pattern.rfind('/')));
        ::close(fd);
        mPath = pattern;
    }
    ~TempVdb() { std::remove(mPath.c_str()); }
    TempVdb(const TempVdb&) = delete;
    TempVdb& operator=(const TempVdb&) = delete;
    const std::string& path() const { return mPath; }

private:
    std::string mPath;
};

// Messages of the file pipeline start with the path; the caller knows no such file.
std::string renamed(const std::string& what, const std::string& path, const std::string& label)
{
    std::string s = what;
    for (size_t at = s.find(path); at != std::string::npos; at = s.find(path, at + label.size()))
        s.replace(at, path.size(), label);
    return s;
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

    TempVdb tmp;
    try {
        openvdb::GridCPtrVec grids{grid.copyGrid()};  // shares the tree
        openvdb::io::File(tmp.path()).write(grids);
    } catch (const std::exception& e) {
        throw InputError(label + ": cannot stage the grid in " + tmp.path() + " (" + e.what() + ")");
    }
    Options o = options;
    o.gridName.clear();  // the file holds this grid alone
    try {
        Result r = simplifyFile(tmp.path(), o, progress);
        r.report.file.clear();
        return r;
    } catch (const InputError& e) {
        throw InputError(renamed(e.what(), tmp.path(), label));
    } catch (const EmptySurfaceError& e) {
        throw EmptySurfaceError(renamed(e.what(), tmp.path(), label));
    }
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

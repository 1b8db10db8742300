// Builds a level-set sphere in memory (or reads a .vdb), simplifies its surface to 10% of the faces with
// vdb_isosimp and writes it; the format follows the output name's extension.
//   simplify_sphere OUT.glb            the in-memory sphere
//   simplify_sphere OUT.ply IN.vdb     the default grid of a file (the library picks it)
#include <vdb_isosimp/vdb_isosimp.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <cstdio>
#include <exception>

namespace {

// Progress and cancellation: return false from update() to stop the run (it throws Cancelled).
class PrintProgress : public vdb_isosimp::Progress {
public:
    bool update(double fraction, uint64_t facesKept) override
    {
        std::fprintf(stderr, "\r%5.1f%% of the blocks, %llu faces kept", 100.0 * fraction,
                     (unsigned long long)facesKept);
        if (fraction >= 1.0) std::fprintf(stderr, "\n");
        return true;
    }
};

} // namespace

int main(int argc, char** argv)
{
    if (argc < 2) {
        std::fprintf(stderr, "usage: %s OUT.{ply,obj,stl,glb} [IN.vdb]\n", argv[0]);
        return 2;
    }
    try {
        vdb_isosimp::Options options;  // defaults: iso 0 for level sets, ratio 0.2, batch 100000, all cores
        options.ratio = 0.1;
        PrintProgress progress;
        vdb_isosimp::Result result;
        if (argc > 2) {
            result = vdb_isosimp::simplifyFile(argv[2], options, &progress);
        } else {
            openvdb::initialize();
            auto grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(/*radius=*/50.0f,
                                                                                  openvdb::Vec3f(0.0f), /*voxel=*/0.5f);
            grid->setName("sphere");
            result = vdb_isosimp::simplifyGrid(*grid, options, &progress);
        }
        vdb_isosimp::WriteOptions write;
        write.normals = true;
        write.objectName = result.report.grid;
        vdb_isosimp::writeMesh(result.mesh, argv[1], write);
        std::printf("%s: %llu -> %llu faces, %llu vertices -> %s\n", result.report.grid.c_str(),
                    (unsigned long long)result.report.facesFull, (unsigned long long)result.report.facesOut,
                    (unsigned long long)result.report.vertsOut, argv[1]);
        return 0;
    } catch (const vdb_isosimp::Cancelled&) {
        std::fprintf(stderr, "cancelled\n");
        return 130;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "simplify_sphere: %s\n", e.what());
        return 1;
    }
}

#include "pipeline/levels.h"

#include "vdb_isosimp/errors.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace vdb_isosimp {

void checkLods(const Options& o)
{
    if (o.lods.empty()) return;
    if (o.targetFaces > 0) throw InputError("a LOD chain takes rates, not a face target");
    for (size_t i = 0; i < o.lods.size(); ++i) {
        const double r = o.lods[i];
        std::ostringstream s;
        if (!(r > 0.0 && r <= 1.0)) s << "LOD rate " << r << " is not in (0, 1]";
        else if (i > 0 && !(r < o.lods[i - 1])) s << "LOD rates must decrease: " << r << " follows " << o.lods[i - 1];
        if (!s.str().empty()) throw InputError(s.str());
    }
}

std::vector<SlabPiece> takePieces(Levels& node)
{
    std::vector<SlabPiece> pieces;
    for (auto& level : node) {
        pieces.push_back(level->takePiece());
        level.reset();
    }
    node.clear();
    return pieces;
}

Mesh makeLevels(Levels& levels, Report& rep, const Options& o, const AttributeSampler& attributes, const Stopwatch& clock)
{
    Mesh mesh;
    for (size_t i = 0; i < o.lods.size(); ++i) {
        Integrator& whole = *levels[i];
        LevelReport level;
        level.ratio = o.lods[i];
        level.facesTarget = i == 0 ? rep.facesTarget : uint64_t(std::llround(level.ratio * double(rep.facesFull)));
        if (i > 0) {
            uint64_t unfinalized = 0;
            whole.finish(level.facesTarget, whole.facesGenerated(), unfinalized);
        }
        mesh = whole.decimator().mesh();
        mesh.attributes = attributes.sample(mesh.points);
        rep.maxErrorAccepted = std::max({rep.maxErrorAccepted, whole.stats().maxErrorAccepted, whole.decimator().maxErrorAccepted()});
        level.facesOut = mesh.triangles.size();
        level.vertsOut = mesh.points.size();
        level.maxErrorAccepted = rep.maxErrorAccepted;
        level.seconds = clock.seconds();
        rep.levels.push_back(level);
        if (o.onLevel) o.onLevel(LevelOfDetail{i, mesh, rep.levels.back(), rep});
        if (i + 1 < o.lods.size()) levels[i].reset();
    }
    // The report's own target and rate are the last level's, like its mesh.
    rep.facesTarget = rep.levels.back().facesTarget;
    rep.ratio = rep.levels.back().ratio;
    return mesh;
}

} // namespace vdb_isosimp

#include "pipeline/levels.h"

#include "vdb_isosimp/errors.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

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

void forEachLevel(Levels& node, const std::function<void(size_t, Integrator&)>& f)
{
    if (node.size() == 1) return f(0, *node.front());
    // Isolated: a thread that waits here for the other levels runs only them, never a slab of the
    // tree (which would open another slab's seams while this node holds its own).
    tbb::this_task_arena::isolate([&] { tbb::parallel_for(size_t(0), node.size(), [&](size_t k) { f(k, *node[k]); }); });
}

uint64_t levelTarget(const Options& o, const Report& rep, size_t level)
{
    if (level == 0) return rep.facesTarget;
    return coarserLevelTarget(o, rep.facesFull, level);
}

uint64_t coarserLevelTarget(const Options& o, uint64_t facesFull, size_t level)
{
    return uint64_t(std::llround(o.lods[level] * double(facesFull)));
}

Mesh takeLevelMesh(Integrator& level, Report& rep)
{
    const double before = level.decimator().parallelSeconds();
    Mesh mesh = level.decimator().takeMesh();
    rep.secondsFinalParallel += level.decimator().parallelSeconds() - before;
    return mesh;
}

Mesh makeLevels(Levels& levels, Report& rep, const Options& o, const AttributeSampler& attributes, const Stopwatch& clock)
{
    Mesh mesh;
    for (size_t i = 0; i < o.lods.size(); ++i) {
        Integrator& whole = *levels[i];
        LevelReport level;
        level.ratio = o.lods[i];
        level.facesTarget = levelTarget(o, rep, i);
        rep.maxErrorAccepted = std::max({rep.maxErrorAccepted, whole.stats().maxErrorAccepted, whole.decimator().maxErrorAccepted()});
        mesh = takeLevelMesh(whole, rep);
        mesh.attributes = attributes.sample(mesh.points);
        level.facesOut = mesh.triangles.size();
        level.vertsOut = mesh.points.size();
        level.stoppedBy = stopReason(level.facesOut, level.facesTarget, whole.boundHeld());
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

// LOD chains (Options::lods): one extraction, and every slab decimated to each rate in turn, a
// coarser level continuing from a copy of the finer one (Integrator::coarser); each level then joins
// up the merge tree and gets its final pass like a single-rate run. So the finest level is the same
// mesh as a run at its rate, and the collapses between levels run slab by slab, in parallel, instead
// of in one serial pass over the finished finest level.
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "core/schedule.h"
#include "pipeline/run_stats.h"
#include "vdb/attribute_sampler.h"
#include "vdb_isosimp/vdb_isosimp.h"

namespace vdb_isosimp {

// A merge tree node: one integrator per level of the chain, finest first (one without a chain).
using Levels = std::vector<std::unique_ptr<Integrator>>;

// The node's pieces for its parent, level by level; the integrators are let go.
std::vector<SlabPiece> takePieces(Levels& node);

// Runs `f` on every level of a node at once (a merge, the final pass): the levels are independent
// meshes, so a chain's node takes as long as its slowest level instead of the sum of all.
void forEachLevel(Levels& node, const std::function<void(size_t level, Integrator& integrator)>& f);

// The face target of level `level` of a chain: the report's target for the first (a run without a
// chain has that one only), the level's rate of the full surface for the others.
uint64_t levelTarget(const Options& options, const Report& report, size_t level);
// The same for a coarser level (level > 0), from the faces of the full-resolution surface alone.
uint64_t coarserLevelTarget(const Options& options, uint64_t facesFull, size_t level);

// @throw InputError for rates that are out of (0, 1] or not strictly decreasing, or a face target
// given with them.
void checkLods(const Options& options);

// A level's mesh after its final pass, the integrator left empty; the seconds its collection runs on
// all threads count among the report's secondsFinalParallel.
Mesh takeLevelMesh(Integrator& level, Report& report);

// The tree's root, every level after its final pass (levelTarget): hands every level, with its
// attributes, to options.onLevel, lets each level but the last go once it is handed on, fills
// report.levels; returns the last level's mesh.
Mesh makeLevels(Levels& levels, Report& report, const Options& options, const AttributeSampler& attributes,
                const Stopwatch& clock);

} // namespace vdb_isosimp

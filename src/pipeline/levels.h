// LOD chains (Options::lods): one extraction, and every slab decimated to each rate in turn, a
// coarser level continuing from a copy of the finer one (Integrator::coarser); each level then joins
// up the merge tree and gets its final pass like a single-rate run. So the finest level is the same
// mesh as a run at its rate, and the collapses between levels run slab by slab, in parallel, instead
// of in one serial pass over the finished finest level.
#pragma once
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

// @throw InputError for rates that are out of (0, 1] or not strictly decreasing, or a face target
// given with them.
void checkLods(const Options& options);

// The tree's root: the first level has had its final pass to its target (report.facesTarget); the
// others get theirs here. Hands every level, with its attributes, to options.onLevel, lets each
// level but the last go once it is handed on, fills report.levels; returns the last level's mesh.
Mesh makeLevels(Levels& levels, Report& report, const Options& options, const AttributeSampler& attributes,
                const Stopwatch& clock);

} // namespace vdb_isosimp

// LOD chains (Options::lods): one extraction at the finest rate, then the final pass decimates the
// finished surface to each rate in turn. Each level is a snapshot of the same decimator, so a coarser
// level continues the collapses of the finer one instead of starting over from the full surface.
#pragma once
#include "core/schedule.h"
#include "pipeline/run_stats.h"
#include "vdb/attribute_sampler.h"
#include "vdb_isosimp/vdb_isosimp.h"

namespace vdb_isosimp {

// @throw InputError for rates that are out of (0, 1] or not strictly decreasing, or a face target
// given with them.
void checkLods(const Options& options);

// `whole` has finished its final pass to the first level's target (report.facesTarget): hands every
// level, with its attributes, to options.onLevel and fills report.levels; returns the last level.
Mesh makeLevels(Integrator& whole, Report& report, const Options& options, const AttributeSampler& attributes,
                const Stopwatch& clock);

} // namespace vdb_isosimp

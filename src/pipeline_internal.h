// Internal seam between the pipeline driver (pipeline.cpp) and its entry points (pipeline_grid.cpp).
#pragma once
#include "vdb_isosimp.h"
#include "volume_reader.h"

#include <functional>
#include <memory>
#include <string>

namespace vdb_isosimp {

// The whole pipeline on the volume `open` returns (called once, after the options are checked):
// `name` is what Report::file holds and what every InputError / EmptySurfaceError message starts
// with. simplifyFile(path) is simplifyVolume([&] { return Volume::open(path, o.gridName); }, path, ...);
// simplifyGrid() passes Volume::fromGrid(), which reads the caller's grid in place.
Result simplifyVolume(const std::function<std::unique_ptr<Volume>()>& open, const std::string& name,
                      const Options& options, Progress* progress);

} // namespace vdb_isosimp

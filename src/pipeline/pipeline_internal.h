// Internal seam between the pipeline driver (pipeline.cpp) and its entry points (pipeline_grid.cpp).
#pragma once
#include "vdb/volume_reader.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <functional>
#include <memory>
#include <string>

namespace vdb_isosimp {

// The whole pipeline on the volume `open` returns (called once, after the options are checked):
// `name` is what Report::file holds and what every InputError / EmptySurfaceError message starts
// with. simplifyFile(path) is simplifyVolume([&] { return Volume::open(path, o.gridName); }, path, ...);
// simplifyGrid() passes Volume::fromGrid(), which reads the caller's grid in place.
using VolumeOpener = std::function<std::unique_ptr<Volume>()>;
Result simplifyVolume(const VolumeOpener& open, const std::string& name, const Options& options, Progress* progress);

} // namespace vdb_isosimp

// A Volume over a grid already in memory (simplifyGrid): the same block list, samples, transform and
// sign convention as Volume::open gives for that grid written to a file, but read only. releaseLeaf()
// does nothing, because the grid belongs to the caller.
#pragma once
#include "volume_reader.h"

#include <openvdb/openvdb.h>

#include <memory>
#include <string>

namespace vdb_isosimp {

// `label` names the grid in error messages and VolumeInfo::file (e.g. "in-memory grid 'density'").
// @throw InputError for a grid that is not float/double, has a non-linear or singular transform, or is
// empty (the same checks, and messages, as Volume::open).
std::unique_ptr<Volume> volumeFromGrid(openvdb::GridBase::ConstPtr grid, const std::string& label);

} // namespace vdb_isosimp

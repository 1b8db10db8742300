// Typed errors the library throws; the programs turn each into one line and an exit code.
#pragma once
#include <stdexcept>
#include <string>

namespace vdb_isosimp {

// Bad input: a file that is missing, not a VDB, a grid of the wrong type, NaN voxels, bad options...
struct InputError : std::runtime_error { using std::runtime_error::runtime_error; };
// The run's estimated peak memory exceeds Options::maxMemoryBytes (an InputError: the input is too
// large for the budget at these settings).
struct MemoryBudgetError : InputError { using InputError::InputError; };
// The output could not be written (directory missing, read-only, disk full).
struct OutputError : std::runtime_error { using std::runtime_error::runtime_error; };
// The iso-value does not cut the volume: nothing to write.
struct EmptySurfaceError : std::runtime_error { using std::runtime_error::runtime_error; };
// The caller's progress callback asked to stop.
struct Cancelled : std::runtime_error { using std::runtime_error::runtime_error; };
// A distributed run stopped because another rank failed: rank 0 reports that rank's error, the others
// end quietly.
struct PeerFailed : std::runtime_error { using std::runtime_error::runtime_error; };

} // namespace vdb_isosimp

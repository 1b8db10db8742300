// Process measurements for the summary line and the report.
#pragma once
#include "core/stopwatch.h"

namespace vdb_isosimp {

// Peak resident set size of this process so far, in MiB.
double peakRssMb();

// CPU seconds (user and system) of this process so far, all its threads.
double processCpuSeconds();

} // namespace vdb_isosimp

#include "pipeline/run_stats.h"

#include <sys/resource.h>

namespace vdb_isosimp {

double peakRssMb()
{
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_maxrss) / 1024.0;  // Linux reports KiB
}

} // namespace vdb_isosimp

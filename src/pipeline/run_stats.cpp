#include "pipeline/run_stats.h"

#include <sys/resource.h>

namespace vdb_isosimp {

double peakRssMb()
{
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_maxrss) / 1024.0;  // Linux reports KiB
}

double processCpuSeconds()
{
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    const auto seconds = [](const timeval& t) { return double(t.tv_sec) + 1e-6 * double(t.tv_usec); };
    return seconds(u.ru_utime) + seconds(u.ru_stime);
}

} // namespace vdb_isosimp

// Process measurements for the summary line and the report.
#pragma once
#include <chrono>

namespace vdb_isosimp {

// Peak resident set size of this process so far, in MiB.
double peakRssMb();

struct Stopwatch {
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
    double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); }
};

} // namespace vdb_isosimp

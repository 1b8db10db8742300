// Seconds since a point in a run: the report's timings, from the file's open to the final pass.
#pragma once
#include <chrono>

namespace vdb_isosimp {

struct Stopwatch {
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
    double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); }
};

} // namespace vdb_isosimp

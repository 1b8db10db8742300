// Small helpers shared by the benchmark baselines: per-phase peak memory and the one-line JSON
// result every baseline prints (the format of baseline_openmesh, plus extra keys).
#pragma once
#include "pipeline/run_stats.h"

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace vdb_isosimp::bench {

// Peak resident memory (VmHWM) in MiB. Unlike getrusage's maximum it can be reset (Linux >= 4.0,
// write "5" to /proc/self/clear_refs), so phases of one run can be measured apart.
inline double highWaterMb()
{
    std::ifstream f("/proc/self/status");
    std::string line;
    while (std::getline(f, line))
        if (line.compare(0, 6, "VmHWM:") == 0) return std::stod(line.substr(6)) / 1024.0;
    return peakRssMb();
}

// Starts a new peak-memory phase. Returns false if the kernel refused (the next highWaterMb() is
// then the process-wide peak, an upper bound).
inline bool resetHighWater()
{
    std::ofstream f("/proc/self/clear_refs");
    f << "5";
    f.close();
    return bool(f);
}

// {"key": value, ...} on one line, keys in insertion order.
class JsonLine {
public:
    JsonLine& str(const std::string& k, const std::string& v) { return raw(k, "\"" + v + "\""); }
    JsonLine& num(const std::string& k, double v, int decimals = 3)
    {
        char b[64];
        std::snprintf(b, sizeof b, "%.*f", decimals, v);
        return raw(k, b);
    }
    JsonLine& count(const std::string& k, unsigned long long v) { return raw(k, std::to_string(v)); }
    std::string text() const
    {
        std::ostringstream s;
        s << "{";
        for (size_t i = 0; i < items_.size(); ++i)
            s << (i ? ", " : "") << "\"" << items_[i].first << "\": " << items_[i].second;
        s << "}";
        return s.str();
    }

private:
    JsonLine& raw(const std::string& k, const std::string& v)
    {
        items_.emplace_back(k, v);
        return *this;
    }
    std::vector<std::pair<std::string, std::string>> items_;
};

} // namespace vdb_isosimp::bench

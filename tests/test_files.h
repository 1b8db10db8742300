// File helpers shared by the tests that drive the programs.
#pragma once
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>

namespace vdb_isosimp::testing {

// The whole file as bytes ("" when missing).
inline std::string slurp(const std::string& path)
{
    std::ifstream f(path, std::ios::binary);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
}

inline bool exists(const std::string& path) { return ::access(path.c_str(), F_OK) == 0; }

} // namespace vdb_isosimp::testing

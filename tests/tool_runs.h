// Running the programs (vdb_isosimp, mesh_error, mesh_stats, make_volume) from the end-to-end tests
// of the error bound, LOD chains and attributes, and reading numbers out of their JSON.
#pragma once
#include "test_files.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <sys/wait.h>
#include <vector>

namespace vdb_isosimp::testing {

struct ToolRun {
    int code = -1;
    std::string out, err;
    double seconds = 0.0;  // wall time of the command
};

// Runs `command` (a shell line) in `dir`, capturing stdout, stderr, the exit code and the wall time.
inline ToolRun runTool(const std::string& dir, const std::string& command)
{
    const std::string out = dir + "/tool_stdout.txt", err = dir + "/tool_stderr.txt";
    const auto start = std::chrono::steady_clock::now();
    const int status = std::system(("cd '" + dir + "' && " + command + " > '" + out + "' 2> '" + err + "' < /dev/null").c_str());
    ToolRun r;
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    std::remove(out.c_str());
    std::remove(err.c_str());
    return r;
}

// The number after "key": in a JSON text (the first occurrence after `after`, when given); NaN if absent.
inline double jsonNumber(const std::string& json, const std::string& key, const std::string& after = "")
{
    size_t from = after.empty() ? 0 : json.find("\"" + after + "\"");
    if (from == std::string::npos) return std::nan("");
    const size_t at = json.find("\"" + key + "\":", from);
    if (at == std::string::npos) return std::nan("");
    return std::strtod(json.c_str() + at + key.size() + 3, nullptr);
}

// A fresh scratch folder named after the running test (and the process), removed at the end.
struct ScratchDir {
    std::string path;
    ScratchDir()
    {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        std::string name = "vdb_isosimp_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name();
        std::replace(name.begin(), name.end(), '/', '_');
        path = (std::filesystem::temp_directory_path() / name).string();
        std::filesystem::remove_all(path);
        std::filesystem::create_directories(path);
    }
    ~ScratchDir() { std::filesystem::remove_all(path); }
};

// Nothing in `dir` but what `keep` names (no mesh, no temporary file left by a failed run).
inline std::string unexpectedFiles(const std::string& dir, const std::vector<std::string>& keep)
{
    std::string extra;
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
        const std::string name = e.path().filename().string();
        if (std::find(keep.begin(), keep.end(), name) == keep.end()) extra += name + " ";
    }
    return extra;
}

inline std::string q(const std::string& s) { return "'" + s + "'"; }

} // namespace vdb_isosimp::testing

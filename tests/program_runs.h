// Scratch folders and program runs shared by the converter's tests (test_raw2vdb, test_image_stacks);
// RAW2VDB_EXE names the program.
#pragma once
#include <gtest/gtest.h>
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

namespace vdb_isosimp::testing {

// A fresh directory for one test (named after the test and the process), removed at the end.
struct TempDir {
    std::filesystem::path path;
    explicit TempDir(const std::string& prefix = "vdb_isosimp_test_")
    {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        path = std::filesystem::temp_directory_path() /
               (prefix + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
        std::filesystem::remove_all(path);
        std::filesystem::create_directories(path);
    }
    ~TempDir() { std::filesystem::remove_all(path); }
    std::filesystem::path operator/(const std::string& name) const { return path / name; }
};

inline std::string readFile(const std::filesystem::path& p)
{
    std::ifstream f(p, std::ios::binary);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
}

inline void writeFile(const std::filesystem::path& p, const std::string& bytes)
{
    std::ofstream f(p, std::ios::binary);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(f.good()) << p;
}

inline std::string shellQuote(const std::string& s)
{
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

struct RunResult {
    int code = -1;
    std::string out, err;
};

// Runs `exe args...` with no input, its stdout and stderr captured through files in `scratch`.
inline RunResult runProgram(const std::string& exe, const std::vector<std::string>& args, const std::filesystem::path& scratch)
{
    std::string cmd = shellQuote(exe);
    for (const auto& a : args) cmd += " " + shellQuote(a);
    const std::filesystem::path out = scratch / "stdout.txt", err = scratch / "stderr.txt";
    cmd += " > " + shellQuote(out.string()) + " 2> " + shellQuote(err.string()) + " < /dev/null";
    const int status = std::system(cmd.c_str());
    RunResult r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = readFile(out);
    r.err = readFile(err);
    std::filesystem::remove(out);
    std::filesystem::remove(err);
    return r;
}

inline RunResult raw2vdb(const std::vector<std::string>& args, const std::filesystem::path& scratch)
{
    return runProgram(RAW2VDB_EXE, args, scratch);
}

// The one float grid of a file raw2vdb wrote.
inline openvdb::FloatGrid::Ptr readVdb(const std::filesystem::path& p)
{
    openvdb::initialize();
    openvdb::io::File file(p.string());
    file.open();
    auto grids = file.getGrids();
    file.close();
    EXPECT_EQ(grids->size(), 1u);
    if (grids->empty()) return nullptr;
    return openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[0]);
}

} // namespace vdb_isosimp::testing

// Hostile inputs, faults and interruption: the programs never crash, hang or leave a bad file.
//
// One table (HostileCases) lists every hostile input with the exit code, a piece of the one-line
// message and, for inputs that do have a surface, the mesh properties that must hold (no NaN,
// closed). The other tests interrupt long runs with signals and write to full or unwritable places.
// Everything runs the real programs as subprocesses, so the sanitizer build checks them too.
#include "mesh_io.h"
#include "mesh_stats.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include "test_files.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <fcntl.h>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace {

using Clock = std::chrono::steady_clock;

using vdb_isosimp::testing::slurp;
using vdb_isosimp::testing::exists;

std::string listDir(const std::string& dir)
{
    std::string out;
    FILE* p = popen(("ls -A '" + dir + "'").c_str(), "r");
    char buf[512];
    while (p && fgets(buf, sizeof buf, p)) out += buf;
    if (p) pclose(p);
    return out;
}

std::string freshDir(const std::string& name)
{
    const std::string d = ::testing::TempDir() + "/hostile_" + name;
    std::system(("chattr -R -i '" + d + "' 2>/dev/null; rm -rf '" + d + "' && mkdir -p '" + d + "'").c_str());
    return d;
}

struct RunResult {
    int code = -1;
    std::string err;
};

// Runs `exe args` in `dir`; stderr captured, exit code decoded (a signal death counts as -signal).
RunResult run(const std::string& dir, const std::string& exe, const std::string& args)
{
    const std::string errFile = dir + "/stderr.log";
    const std::string cmd = "cd '" + dir + "' && exec '" + exe + "' " + args + " 2> '" + errFile + "' > /dev/null";
    const int status = std::system(cmd.c_str());
    RunResult r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : WIFSIGNALED(status) ? -WTERMSIG(status) : -1000;
    r.err = slurp(errFile);
    std::remove(errFile.c_str());
    return r;
}

// Files in `dir` other than the inputs (*.vdb, *.raw) and the stderr log: what a run left behind.
std::string leftovers(const std::string& dir)
{
    std::string out;
    FILE* p = popen(("ls -A '" + dir + "' | grep -v '\\.vdb$\\|\\.raw$\\|\\.log$'").c_str(), "r");
    char buf[512];
    while (p && fgets(buf, sizeof buf, p)) out += buf;
    if (p) pclose(p);
    return out;
}

void write(openvdb::GridBase::Ptr grid, const std::string& path)
{
    openvdb::initialize();
    openvdb::io::File f(path);
    f.write({grid});
    f.close();
}

openvdb::FloatGrid::Ptr fogGrid(float background = 0.0f)
{
    auto g = openvdb::FloatGrid::create(background);
    g->setName("density");
    g->setGridClass(openvdb::GRID_FOG_VOLUME);
    return g;
}

// A dense block of n^3 active voxels [0, n) with values f(x, y, z).
openvdb::FloatGrid::Ptr denseFog(int nx, int ny, int nz, const std::function<float(int, int, int)>& f, float bg = 0.0f)
{
    auto g = fogGrid(bg);
    auto acc = g->getAccessor();
    for (int z = 0; z < nz; ++z)
        for (int y = 0; y < ny; ++y)
            for (int x = 0; x < nx; ++x) acc.setValueOn(openvdb::Coord(x, y, z), f(x, y, z));
    return g;
}

// A level-set sphere of radius 12 voxels; the voxel size and origin are set through an affine map
// (OpenVDB itself refuses a map whose determinant is below ~1e-15, so a uniform 1e-6 voxel cannot
// exist in a .vdb: 1e-6 is tested on two axes, and 1e-4 uniformly).
openvdb::FloatGrid::Ptr sphere(openvdb::Vec3d voxel, openvdb::Vec3d origin = openvdb::Vec3d(0))
{
    auto g = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(12.0f, openvdb::Vec3f(0), 1.0f);
    g->setName("surface");
    if (voxel != openvdb::Vec3d(1) || origin != openvdb::Vec3d(0)) {
        openvdb::Mat4d m = openvdb::Mat4d::identity();
        for (int i = 0; i < 3; ++i) m[i][i] = voxel[i];
        m.setTranslation(origin);
        g->setTransform(openvdb::math::Transform::Ptr(
            new openvdb::math::Transform(openvdb::math::MapBase::Ptr(new openvdb::math::AffineMap(m)))));
    }
    return g;
}

struct HostileCase {
    std::string name;
    std::function<void(const std::string& dir)> make;  // writes in.vdb (or whatever args name)
    std::string args;                                    // after the program name; output out.ply
    int code;                                            // expected exit code
    std::string message;                                 // part of the one stderr line ("" on success)
    bool closed = false;                                 // success: the mesh must be closed
};

std::vector<HostileCase> hostileCases()
{
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    std::vector<HostileCase> c;
    // ---- numerical hostility: a surface where there is one, never a NaN, closed where closed
    c.push_back({"constant_grid", [](const std::string& d) {
                     write(denseFog(24, 24, 24, [](int, int, int) { return 1.0f; }, 1.0f), d + "/in.vdb");
                 }, "in.vdb -o out.ply", 3, "no surface at iso-value 1"});
    c.push_back({"constant_grid_iso_equal", [](const std::string& d) {
                     write(denseFog(24, 24, 24, [](int, int, int) { return 0.5f; }, 0.5f), d + "/in.vdb");
                 }, "in.vdb --iso 0.5 -o out.ply", 3, "no surface at iso-value 0.5"});
    c.push_back({"checkerboard", [](const std::string& d) {
                     write(denseFog(24, 24, 24, [](int x, int y, int z) { return ((x + y + z) & 1) ? 1.0f : -1.0f; }, -1.0f),
                           d + "/in.vdb");
                 }, "in.vdb --iso 0 -r 0.2 -o out.ply", 0, "", true});
    c.push_back({"checkerboard_full_resolution", [](const std::string& d) {
                     write(denseFog(16, 16, 16, [](int x, int y, int z) { return ((x + y + z) & 1) ? 1.0f : -1.0f; }, -1.0f),
                           d + "/in.vdb");
                 }, "in.vdb --iso 0 -r 1 -o out.ply", 0, "", true});
    // A cube whose faces lie exactly on voxel planes holding the iso-value.
    c.push_back({"iso_on_whole_planes", [](const std::string& d) {
                     auto g = denseFog(33, 33, 33, [](int x, int y, int z) {
                         return float(8 - std::max({std::abs(x - 16), std::abs(y - 16), std::abs(z - 16)}));
                     }, -8.0f);
                     write(g, d + "/in.vdb");
                 }, "in.vdb --iso 0 -r 0.1 -o out.ply", 0, "", true});
    c.push_back({"iso_on_whole_planes_full_resolution", [](const std::string& d) {
                     auto g = denseFog(33, 33, 33, [](int x, int y, int z) {
                         return float(8 - std::max({std::abs(x - 16), std::abs(y - 16), std::abs(z - 16)}));
                     }, -8.0f);
                     write(g, d + "/in.vdb");
                 }, "in.vdb --iso 0 -r 1 -o out.ply", 0, "", true});
    c.push_back({"tiny_voxels_1em6_on_two_axes", [](const std::string& d) { write(sphere({1e-6, 1e-6, 1}), d + "/in.vdb"); },
                 "in.vdb -r 0.2 -o out.ply", 0, "", true});
    c.push_back({"tiny_voxels_1em4", [](const std::string& d) { write(sphere(openvdb::Vec3d(1e-4)), d + "/in.vdb"); },
                 "in.vdb -r 0.2 -o out.ply", 0, "", true});
    c.push_back({"huge_voxels_1ep6", [](const std::string& d) { write(sphere(openvdb::Vec3d(1e6)), d + "/in.vdb"); },
                 "in.vdb -r 0.2 -o out.ply", 0, "", true});
    c.push_back({"far_origin_1ep7", [](const std::string& d) { write(sphere(openvdb::Vec3d(1), openvdb::Vec3d(1e7, -1e7, 1e7)), d + "/in.vdb"); },
                 "in.vdb -r 0.2 -o out.ply", 0, "", true});
    c.push_back({"single_active_voxel", [](const std::string& d) {
                     auto g = fogGrid();
                     g->tree().setValue(openvdb::Coord(3, -5, 7), 1.0f);
                     write(g, d + "/in.vdb");
                 }, "in.vdb -o out.ply", 0, "", true});
    c.push_back({"one_voxel_thick_slab", [](const std::string& d) {
                     write(denseFog(40, 40, 1, [](int, int, int) { return 1.0f; }), d + "/in.vdb");
                 }, "in.vdb --iso 0.5 -r 0.2 -o out.ply", 0, "", true});
    c.push_back({"one_voxel_thick_line", [](const std::string& d) {
                     write(denseFog(64, 1, 1, [](int, int, int) { return 1.0f; }), d + "/in.vdb");
                 }, "in.vdb --iso 0.5 -r 0.2 -o out.ply", 0, "", true});
    // ---- bad values
    c.push_back({"nan_voxel", [nan](const std::string& d) {
                     auto g = denseFog(8, 8, 8, [](int, int, int) { return 1.0f; });
                     g->tree().setValue(openvdb::Coord(2, 3, 4), nan);
                     write(g, d + "/in.vdb");
                 }, "in.vdb --iso 0.5 -o out.ply", 1, "is nan (NaN/Inf values are not allowed)"});
    c.push_back({"inf_tile", [inf](const std::string& d) {
                     auto g = fogGrid();
                     g->tree().addTile(1, openvdb::Coord(0), inf, true);
                     write(g, d + "/in.vdb");
                 }, "in.vdb --iso 0.5 -o out.ply", 1, "non-finite"});
    c.push_back({"nan_background", [nan](const std::string& d) {
                     auto g = fogGrid(nan);
                     g->tree().setValue(openvdb::Coord(0), 1.0f);
                     write(g, d + "/in.vdb");
                 }, "in.vdb --iso 0.5 -o out.ply", 1, "non-finite background"});
    // ---- bad geometry
    c.push_back({"index_box_beyond_range", [](const std::string& d) {
                     auto g = fogGrid();
                     g->tree().setValue(openvdb::Coord(1000000000, 0, 0), 1.0f);
                     write(g, d + "/in.vdb");
                 }, "in.vdb --iso 0.5 -o out.ply", 1, "lies outside the supported index range"});
    c.push_back({"index_box_negative_edge", [](const std::string& d) {
                     auto g = fogGrid();
                     g->tree().setValue(openvdb::Coord(0, -600000, 0), 1.0f);
                     write(g, d + "/in.vdb");
                 }, "in.vdb --iso 0.5 -o out.ply", 1, "lies outside the supported index range"});
    c.push_back({"non_linear_transform", [](const std::string& d) {
                     auto g = sphere(openvdb::Vec3d(1));
                     g->setTransform(openvdb::math::Transform::createFrustumTransform(
                         openvdb::BBoxd(openvdb::Vec3d(-20), openvdb::Vec3d(20)), 0.5, 10.0, 1.0));
                     write(g, d + "/in.vdb");
                 }, "in.vdb -o out.ply", 1, "non-linear transform"});
    // ---- bad files
    c.push_back({"missing_file", [](const std::string&) {}, "in.vdb -o out.ply", 1, "in.vdb: cannot open file"});
    c.push_back({"directory_as_input", [](const std::string& d) { std::system(("mkdir '" + d + "/in.vdb'").c_str()); },
                 "in.vdb -o out.ply", 1, "is a directory"});
    c.push_back({"empty_file", [](const std::string& d) { std::ofstream(d + "/in.vdb"); }, "in.vdb -o out.ply", 1,
                 "not a readable OpenVDB file"});
    c.push_back({"text_file", [](const std::string& d) { std::ofstream(d + "/in.vdb") << "#!/bin/sh\necho hi\n"; },
                 "in.vdb -o out.ply", 1, "not a readable OpenVDB file"});
    for (int cut : {12, 40, 200, 3000, -1}) {
        c.push_back({"truncated_at_" + (cut < 0 ? std::string("last_byte") : std::to_string(cut)), [cut](const std::string& d) {
                         write(sphere(openvdb::Vec3d(1)), d + "/whole.vdb");
                         const std::string bytes = slurp(d + "/whole.vdb");
                         std::ofstream(d + "/in.vdb", std::ios::binary) << bytes.substr(0, cut < 0 ? bytes.size() - 1 : size_t(cut));
                         std::remove((d + "/whole.vdb").c_str());
                     }, "in.vdb -o out.ply", 1, cut < 40 ? "in.vdb: " : "truncated or damaged OpenVDB file"});
    }
    // ---- resources and options
    c.push_back({"memory_above_max_memory", [](const std::string& d) { write(sphere(openvdb::Vec3d(1)), d + "/in.vdb"); },
                 "in.vdb --max-memory 10M -o out.ply", 1, "exceeds the limit of 10 MiB"});
    c.push_back({"max_memory_not_a_size", [](const std::string& d) { write(sphere(openvdb::Vec3d(1)), d + "/in.vdb"); },
                 "in.vdb --max-memory lots -o out.ply", 2, "--max-memory: 'lots' is not a size"});
    c.push_back({"max_memory_zero_is_no_limit", [](const std::string& d) { write(sphere(openvdb::Vec3d(1)), d + "/in.vdb"); },
                 "in.vdb --max-memory 0 -o out.ply", 0, "", true});
    c.push_back({"ratio_nan", [](const std::string& d) { write(sphere(openvdb::Vec3d(1)), d + "/in.vdb"); },
                 "in.vdb --ratio nan -o out.ply", 2, "ratio"});
    c.push_back({"iso_inf", [](const std::string& d) { write(sphere(openvdb::Vec3d(1)), d + "/in.vdb"); },
                 "in.vdb --iso inf -o out.ply", 2, "--iso must be a finite number"});
    c.push_back({"faces_huge", [](const std::string& d) { write(sphere(openvdb::Vec3d(1)), d + "/in.vdb"); },
                 "in.vdb --faces 18446744073709551615 -o out.ply", 0, "", true});
    // ---- bad output places (the read-only directory and the full disk have their own tests)
    c.push_back({"output_is_a_directory", [](const std::string& d) {
                     write(sphere(openvdb::Vec3d(1)), d + "/in.vdb");
                     std::system(("mkdir '" + d + "/out.ply'").c_str());
                 }, "in.vdb -o out.ply", 1, "out.ply: cannot create output file (Is a directory)"});
    c.push_back({"output_parent_is_a_file", [](const std::string& d) {
                     write(sphere(openvdb::Vec3d(1)), d + "/in.vdb");
                     std::ofstream(d + "/file.vdb") << "x";
                 }, "in.vdb -o file.vdb/out.ply", 1, "cannot create output file (Not a directory)"});
    c.push_back({"output_links_to_dev_full", [](const std::string& d) {
                     write(sphere(openvdb::Vec3d(1)), d + "/in.vdb");
                     std::system(("ln -s /dev/full '" + d + "/out.ply'").c_str());
                 }, "in.vdb -o out.ply", 1, "out.ply: write failed (No space left on device)"});
    c.push_back({"report_to_dev_full", [](const std::string& d) { write(sphere(openvdb::Vec3d(1)), d + "/in.vdb"); },
                 "in.vdb -o out.ply --report /dev/full", 1, "/dev/full: cannot write report (No space left on device)", true});
    return c;
}

class Hostile : public ::testing::TestWithParam<HostileCase> {};

TEST_P(Hostile, ExitCodeMessageAndMesh)
{
    const HostileCase& hc = GetParam();
    const std::string d = freshDir(hc.name);
    hc.make(d);
    const RunResult r = run(d, VDB_ISOSIMP_EXE, hc.args + " -q");
    EXPECT_EQ(r.code, hc.code) << r.err;
    if (!hc.message.empty()) {
        EXPECT_NE(r.err.find(hc.message), std::string::npos) << "stderr: " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "not one line: " << r.err;
    } else {
        EXPECT_EQ(r.err, "");
    }
    for (const char* bad : {"terminate", "Sanitizer", "runtime error", "Aborted"})
        EXPECT_EQ(r.err.find(bad), std::string::npos) << r.err;
    const std::string out = d + "/out.ply";
    struct stat st {};
    const bool regularOut = ::lstat(out.c_str(), &st) == 0 && S_ISREG(st.st_mode);
    if (hc.code != 0 && !hc.closed) {
        EXPECT_FALSE(regularOut) << "a failed run left " << out;
        const std::string left = leftovers(d);
        EXPECT_TRUE(left.empty() || left == "out.ply\n" || left == "file.vdb\n") << "left behind: " << left;
    }
    if (hc.closed) {
        ASSERT_TRUE(regularOut) << r.err;
        const vdb_isosimp::Mesh m = vdb_isosimp::eval::readMesh(out);
        for (const auto& p : m.points)
            for (float v : p) ASSERT_TRUE(std::isfinite(v)) << "non-finite vertex in " << hc.name;
        const auto s = vdb_isosimp::eval::computeMeshStats(m);
        EXPECT_TRUE(s.closed()) << hc.name << ": " << s.boundaryEdges << " boundary, " << s.nonManifoldEdges
                                << " non-manifold edges, " << s.faces << " faces";
        EXPECT_TRUE(s.oriented()) << hc.name << ": " << s.misorientedEdges << " misoriented edges";
        EXPECT_GT(s.signedVolume, 0.0) << hc.name;
        EXPECT_EQ(leftovers(d), "out.ply\n");
    }
}

INSTANTIATE_TEST_SUITE_P(Table, Hostile, ::testing::ValuesIn(hostileCases()),
                         [](const ::testing::TestParamInfo<HostileCase>& i) { return i.param.name; });

// ---------------------------------------------------------------------------------------------
// Interruption

// What interrupt() saw.
struct Interrupted {
    int code = -1;
    double stopSeconds = 0;
    std::string err;
};

// Whether process `pid` has a handler for `sig`: bit sig-1 of the hexadecimal SigCgt mask.
bool catches(pid_t pid, int sig)
{
    std::ifstream f("/proc/" + std::to_string(pid) + "/status");
    std::string line;
    while (std::getline(f, line)) {
        if (line.rfind("SigCgt:", 0) == 0) return (std::stoull(line.substr(7), nullptr, 16) >> (sig - 1)) & 1u;
    }
    return false;
}

// Starts `exe args` in `dir`, sends `sig` after `delay`, returns (exit status, seconds from the
// signal to the exit). stderr goes to dir/stderr.log. With `afterHandlers` the delay counts from the
// moment the program catches `sig` (its SigCgt in /proc), not from its start: loading the shared
// libraries alone takes over a second on a cold, busy machine, and a signal then meets no handler.
Interrupted interrupt(const std::string& dir, const std::vector<std::string>& argv, int sig, double delay,
                      bool afterHandlers = false)
{
    const pid_t pid = ::fork();
    if (pid == 0) {
        if (::chdir(dir.c_str()) != 0) ::_exit(120);
        const int fd = ::open("stderr.log", O_WRONLY | O_CREAT | O_TRUNC, 0644);
        ::dup2(fd, 2);
        std::vector<char*> a;
        for (const auto& s : argv) a.push_back(const_cast<char*>(s.c_str()));
        a.push_back(nullptr);
        ::execv(a[0], a.data());
        ::_exit(121);
    }
    Interrupted r;
    int status = 0;
    // The program ended before the signal (before it caught it, or within the delay): r.code -2000.
    const auto ended = [&] { return ::waitpid(pid, &status, WNOHANG) == pid; };
    for (int waited = 0; afterHandlers && !catches(pid, sig); ++waited) {
        if (ended()) {
            r.code = -2000;
            return r;
        }
        if (waited == 60000) {  // a minute without a handler: the test fails on the default action
            ::kill(pid, SIGKILL);
            ::waitpid(pid, &status, 0);
            r.code = -SIGKILL;
            return r;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(delay));
    if (ended()) {  // the volume is too small
        r.code = -2000;
        return r;
    }
    const auto t0 = Clock::now();
    ::kill(pid, sig);
    ::waitpid(pid, &status, 0);
    r.stopSeconds = std::chrono::duration<double>(Clock::now() - t0).count();
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
    r.err = slurp(dir + "/stderr.log");
    std::remove((dir + "/stderr.log").c_str());
    return r;
}

// A volume whose run takes many seconds: a gyroid fog filling 256^3 voxels with a 20-voxel period
// (~10M faces; about 8 s on 2 cores, well past the latest signal below).
const std::string& largeVolume()
{
    static const std::string path = [] {
        // One per process: ctest runs these tests in parallel, and a shared file would be deleted and
        // rewritten under a run that is reading it.
        const std::string d = freshDir("large_" + std::to_string(::getpid()));
        const std::string p = d + "/gyroid.vdb";
        const std::string cmd = std::string("'") + MAKE_VOLUME_EXE + "' gyroid -n 256 --period 20 -o '" + p + "' > /dev/null";
        if (std::system(cmd.c_str()) != 0) return std::string();
        return p;
    }();
    return path;
}

class Interrupt : public ::testing::TestWithParam<std::tuple<int, double>> {};

TEST_P(Interrupt, StopsWithinOneSecondAndLeavesNothing)
{
    const int sig = std::get<0>(GetParam());
    const double delay = std::get<1>(GetParam());
    const std::string& vol = largeVolume();
    ASSERT_FALSE(vol.empty());
    const std::string d = freshDir("interrupt_" + std::to_string(sig) + "_" + std::to_string(int(delay * 10)));
    // The earliest signal tests the start itself; the others come that long after the handlers are in.
    const bool atStart = delay < 0.2;
    const Interrupted r =
        interrupt(d, {VDB_ISOSIMP_EXE, vol, "-q", "-r", "0.1", "-o", "out.ply", "--report", "r.json"}, sig, delay, !atStart);
    ASSERT_NE(r.code, -2000) << "the run ended before the signal: use a larger volume";
    EXPECT_LT(r.stopSeconds, 1.0);
    if (atStart && r.code == -sig) {
        // Before main installs its handlers (libraries still loading) the default action applies:
        // the process dies by the signal, before it could have created any file.
    } else {
        EXPECT_EQ(r.code, 128 + sig) << r.err;
        EXPECT_NE(r.err.find("interrupted"), std::string::npos) << r.err;
    }
    EXPECT_EQ(leftovers(d), "") << "files left behind";
    std::printf("signal %d after %.1f s: exit %d, stopped in %.3f s\n", sig, delay, r.code, r.stopSeconds);
}

INSTANTIATE_TEST_SUITE_P(Signals, Interrupt,
                         ::testing::Values(std::make_tuple(SIGINT, 1.0), std::make_tuple(SIGTERM, 1.0),
                                           std::make_tuple(SIGINT, 4.0), std::make_tuple(SIGINT, 0.05)),
                         [](const ::testing::TestParamInfo<std::tuple<int, double>>& i) {
                             return std::string(std::get<0>(i.param) == SIGINT ? "SIGINT" : "SIGTERM") + "_after_" +
                                    std::to_string(int(std::get<1>(i.param) * 1000)) + "ms";
                         });

// A raw volume big enough for raw2vdb to take a while (256^3 float noise, 64 MiB).
std::string largeRaw(const std::string& dir)
{
    const std::string p = dir + "/big.raw";
    std::ofstream f(p, std::ios::binary);
    std::vector<float> slab(256 * 256);
    uint32_t h = 12345;
    for (int z = 0; z < 256; ++z) {
        for (auto& v : slab) {
            h = h * 1664525u + 1013904223u;
            v = float(h >> 8) / float(1 << 24);
        }
        f.write(reinterpret_cast<const char*>(slab.data()), std::streamsize(slab.size() * sizeof(float)));
    }
    return p;
}

TEST(Interrupt, Raw2vdbStopsAndLeavesNothing)
{
    const std::string d = freshDir("interrupt_raw2vdb");
    largeRaw(d);
    for (int sig : {SIGINT, SIGTERM}) {
        // A tenth of a second into the conversion (about 0.6 s of work on an idle machine).
        const Interrupted r =
            interrupt(d, {RAW2VDB_EXE, "big.raw", "--dims", "256,256,256", "--type", "f32", "-q", "-o", "out.vdb"}, sig, 0.1, true);
        if (r.code == -2000) GTEST_SKIP() << "conversion finished before the signal";
        EXPECT_EQ(r.code, 128 + sig) << r.err;
        EXPECT_LT(r.stopSeconds, 1.0);
        EXPECT_FALSE(exists(d + "/out.vdb"));
        EXPECT_EQ(leftovers(d), "") << "files left behind";
    }
}

// ---------------------------------------------------------------------------------------------
// Disk faults

// A directory nothing can be created in, even by root: the immutable attribute where the file
// system has it (root ignores permission bits), else mode 555 for an ordinary user.
struct ReadOnlyDir {
    std::string path;
    bool ok = false;
    std::string how;
    explicit ReadOnlyDir(const std::string& p) : path(p)
    {
        std::system(("mkdir -p '" + p + "'").c_str());
        if (::geteuid() == 0) {
            ok = std::system(("chattr +i '" + p + "' 2>/dev/null").c_str()) == 0;
            how = "chattr +i";
        } else {
            ok = ::chmod(p.c_str(), 0555) == 0;
            how = "chmod 555";
        }
    }
    ~ReadOnlyDir()
    {
        if (::geteuid() == 0) std::system(("chattr -i '" + path + "' 2>/dev/null").c_str());
        ::chmod(path.c_str(), 0755);
    }
};

TEST(DiskFaults, ReadOnlyDirectory)
{
    const std::string d = freshDir("readonly");
    write(sphere(openvdb::Vec3d(1)), d + "/in.vdb");
    ReadOnlyDir ro(d + "/ro");
    if (!ro.ok) GTEST_SKIP() << "cannot make a read-only directory here (" << ro.how << ")";
    const RunResult r = run(d, VDB_ISOSIMP_EXE, "in.vdb -q -o ro/out.ply");
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_TRUE(r.err.find("ro/out.ply: cannot create output file (Permission denied)") != std::string::npos ||
                r.err.find("ro/out.ply: cannot create output file (Operation not permitted)") != std::string::npos)
        << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(listDir(ro.path), "");
    std::ofstream(d + "/one.raw", std::ios::binary) << '\1';
    const RunResult c = run(d, RAW2VDB_EXE, "one.raw --dims 1,1,1 --type u8 -q -o ro/out.vdb");
    EXPECT_EQ(c.code, 1) << c.err;
    EXPECT_NE(c.err.find("ro/out.vdb"), std::string::npos) << c.err;
    EXPECT_EQ(listDir(ro.path), "");
}

TEST(DiskFaults, DevFull)
{
    const std::string d = freshDir("devfull");
    write(sphere(openvdb::Vec3d(1)), d + "/in.vdb");
    std::system(("ln -s /dev/full '" + d + "/full.ply' && ln -s /dev/full '" + d + "/full.vdb'").c_str());
    // The mesh goes into the device (not a renamed file over it) and the failure is reported.
    RunResult r = run(d, VDB_ISOSIMP_EXE, "in.vdb -q -o full.ply");
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(r.err, "vdb_isosimp: full.ply: write failed (No space left on device)\n");
    r = run(d, VDB_ISOSIMP_EXE, "in.vdb -q -o ok.ply --trace /dev/full");
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(r.err, "vdb_isosimp: /dev/full: cannot write report (No space left on device)\n");
    // A .vdb needs a seekable file: raw2vdb refuses a device before converting.
    std::ofstream(d + "/tiny.raw", std::ios::binary) << std::string(8, '\1');
    r = run(d, RAW2VDB_EXE, "tiny.raw --dims 2,2,2 --type u8 -q -o /dev/full");
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(r.err, "raw2vdb: /dev/full: cannot write: not a regular file (a .vdb file must be seekable)\n");
    r = run(d, RAW2VDB_EXE, "tiny.raw --dims 2,2,2 --type u8 -q -o full.vdb");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("full.vdb: cannot write: not a regular file"), std::string::npos) << r.err;
    // /dev/full is still the device, the links are still links, nothing else was created.
    struct stat st {};
    ASSERT_EQ(::stat("/dev/full", &st), 0);
    EXPECT_TRUE(S_ISCHR(st.st_mode));
    ASSERT_EQ(::lstat((d + "/full.ply").c_str(), &st), 0);
    EXPECT_TRUE(S_ISLNK(st.st_mode));
    ASSERT_EQ(::lstat((d + "/full.vdb").c_str(), &st), 0);
    EXPECT_TRUE(S_ISLNK(st.st_mode));
    EXPECT_EQ(leftovers(d), "full.ply\nok.ply\n");
}

// A real file system that fills up mid-write: a 64 KiB tmpfs (needs the right to mount, as in CI).
TEST(DiskFaults, FullFileSystem)
{
    const std::string d = freshDir("fullfs");
    write(sphere(openvdb::Vec3d(1)), d + "/in.vdb");
    const std::string mnt = d + "/small";
    std::system(("mkdir -p '" + mnt + "'").c_str());
    if (::mount("tmpfs", mnt.c_str(), "tmpfs", 0, "size=64k") != 0) GTEST_SKIP() << "cannot mount a tmpfs here";
    struct Unmount {
        std::string p;
        ~Unmount() { ::umount(p.c_str()); }
    } unmount{mnt};
    RunResult r = run(d, VDB_ISOSIMP_EXE, "in.vdb -q -r 1 -o small/out.ply");
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(r.err, "vdb_isosimp: small/out.ply: write failed (No space left on device)\n");
    EXPECT_EQ(listDir(mnt), "");
    // raw2vdb: a 128^3 noise volume does not fit in 64 KiB either.
    {
        std::ofstream f(d + "/noise.raw", std::ios::binary);
        uint32_t h = 7;
        for (int i = 0; i < 128 * 128 * 128; ++i) {
            h = h * 1664525u + 1013904223u;
            f.put(char(h >> 24));
        }
    }
    r = run(d, RAW2VDB_EXE, "noise.raw --dims 128,128,128 --type u8 -q -o small/out.vdb");
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(r.err, "raw2vdb: small/out.vdb: cannot write: No space left on device\n");
    EXPECT_EQ(listDir(mnt), "");
}

} // namespace

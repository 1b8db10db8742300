// The vdb_isosimp program as a user meets it: bad input gives one clear line on stderr, a non-zero
// exit code and no output file; good input gives the mesh, the summary and the JSON report, byte for
// byte the same for any thread count.
#include "test_grids.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include "test_files.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <sys/wait.h>
#include <unistd.h>

namespace vt = vdb_isosimp::testing;

namespace {

struct RunResult {
    int code = -1;
    std::string err;
};

using vdb_isosimp::testing::slurp;
using vdb_isosimp::testing::exists;

// Runs the program in `dir` with `args`; captures stderr and the exit code.
RunResult run(const std::string& dir, const std::string& args)
{
    const std::string errFile = dir + "/stderr.txt";
    const std::string cmd = "cd '" + dir + "' && '" + VDB_ISOSIMP_EXE + "' " + args + " 2> '" + errFile + "' > /dev/null";
    const int status = std::system(cmd.c_str());
    RunResult r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.err = slurp(errFile);
    std::remove(errFile.c_str());
    return r;
}

std::string freshDir(const std::string& name)
{
    const std::string d = ::testing::TempDir() + "/cli_" + name;
    std::system(("rm -rf '" + d + "' && mkdir -p '" + d + "'").c_str());
    return d;
}

// Nothing but the one expected line, and no mesh or temporary file left in the folder.
void expectCleanFailure(const RunResult& r, int code, const std::string& needle, const std::string& dir)
{
    EXPECT_EQ(r.code, code) << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << "stderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "not one line: " << r.err;
    EXPECT_EQ(r.err.find("terminate"), std::string::npos);
    const std::string listing = [&] {
        std::string out;
        FILE* p = popen(("ls -A '" + dir + "' | grep -v '\\.vdb$\\|\\.txt$'").c_str(), "r");
        char buf[256];
        while (p && fgets(buf, sizeof buf, p)) out += buf;
        if (p) pclose(p);
        return out;
    }();
    EXPECT_EQ(listing, "") << "files left behind";
}

std::string sphere(const std::string& dir)
{
    openvdb::initialize();
    auto g = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(20.0f, openvdb::Vec3f(0), 0.5f);
    g->setName("sphere");
    const std::string path = dir + "/sphere.vdb";
    openvdb::io::File(path).write({g});
    return path;
}

} // namespace

TEST(Cli, MissingFile)
{
    const auto d = freshDir("missing");
    expectCleanFailure(run(d, "nope.vdb"), 1, "nope.vdb: cannot open file", d);
}

TEST(Cli, NotAVdbFile)
{
    const auto d = freshDir("notvdb");
    std::ofstream(d + "/fake.vdb") << "this is not a volume\n";
    expectCleanFailure(run(d, "fake.vdb -o out.ply"), 1, "fake.vdb: not a readable OpenVDB file", d);
}

TEST(Cli, NoSuchGrid)
{
    const auto d = freshDir("nogrid");
    sphere(d);
    expectCleanFailure(run(d, "sphere.vdb --grid density -o out.ply"), 1, "no grid named 'density' (grids: sphere)", d);
}

TEST(Cli, WrongValueType)
{
    const auto d = freshDir("vec3");
    openvdb::initialize();
    auto g = openvdb::Vec3SGrid::create();
    g->setName("vel");
    g->tree().setValue(openvdb::Coord(0), openvdb::Vec3s(1, 0, 0));
    openvdb::io::File(d + "/vel.vdb").write({g});
    expectCleanFailure(run(d, "vel.vdb --grid vel -o out.ply"), 1, "value type vec3s", d);
    expectCleanFailure(run(d, "vel.vdb -o out.ply"), 1, "no float or double grid", d);
}

TEST(Cli, EmptyGrid)
{
    const auto d = freshDir("empty");
    openvdb::initialize();
    auto g = openvdb::FloatGrid::create(1.0f);
    g->setName("nothing");
    openvdb::io::File(d + "/empty.vdb").write({g});
    expectCleanFailure(run(d, "empty.vdb -o out.ply"), 1, "grid 'nothing' is empty", d);
}

TEST(Cli, IsoOutsideValueRange)
{
    const auto d = freshDir("iso");
    sphere(d);
    expectCleanFailure(run(d, "sphere.vdb --iso 50 -o out.ply"), 3, "no surface at iso-value 50", d);
}

TEST(Cli, NanVoxel)
{
    const auto d = freshDir("nan");
    openvdb::initialize();
    auto g = openvdb::FloatGrid::create(0.0f);
    g->setName("density");
    for (int i = 0; i < 10; ++i) g->tree().setValue(openvdb::Coord(i, 0, 0), 1.0f);
    g->tree().setValue(openvdb::Coord(3, 0, 0), std::numeric_limits<float>::quiet_NaN());
    openvdb::io::File(d + "/nan.vdb").write({g});
    expectCleanFailure(run(d, "nan.vdb --iso 0.5 -o out.ply"), 1, "nan.vdb: voxel [3, 0, 0] of grid 'density' is nan", d);
}

TEST(Cli, RatioOutOfRange)
{
    const auto d = freshDir("ratio");
    sphere(d);
    expectCleanFailure(run(d, "sphere.vdb --ratio 0 -o out.ply"), 2, "ratio", d);
    expectCleanFailure(run(d, "sphere.vdb --ratio 1.5 -o out.ply"), 2, "ratio", d);
    expectCleanFailure(run(d, "sphere.vdb --ratio -1 -o out.ply"), 2, "ratio", d);
    expectCleanFailure(run(d, "sphere.vdb --ratio 0.5 --faces 100 -o out.ply"), 2, "excludes", d);
}

TEST(Cli, UnwritableOutput)
{
    const auto d = freshDir("unwritable");
    sphere(d);
    expectCleanFailure(run(d, "sphere.vdb -o no/such/dir/out.ply"), 1, "no/such/dir/out.ply: cannot create output file", d);
    expectCleanFailure(run(d, "sphere.vdb -o out.xyz"), 1, "unsupported output format", d);
    if (::geteuid() != 0) {  // root ignores directory permissions
        std::system(("mkdir -p '" + d + "/ro' && chmod 555 '" + d + "/ro'").c_str());
        expectCleanFailure(run(d, "sphere.vdb -o ro/out.ply"), 1, "cannot create output file", d);
    }
}

TEST(Cli, DefaultOutputNameReportAndSummary)
{
    const auto d = freshDir("ok");
    sphere(d);
    const RunResult r = run(d, "sphere.vdb --report report.json");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(exists(d + "/sphere.ply"));
    EXPECT_NE(r.err.find("faces"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("peak"), std::string::npos) << r.err;
    const std::string json = slurp(d + "/report.json");
    for (const char* key : {"faces_full", "faces_out", "verts_out", "decimations", "max_intermediate_faces",
                            "max_uncontractible_faces", "seconds", "seconds_slabs", "seconds_final", "peak_rss_mb"})
        EXPECT_NE(json.find(std::string("\"") + key + "\""), std::string::npos) << key;
    // The two phases are parts of the whole run.
    auto number = [&](const std::string& key) { return std::stod(json.substr(json.find("\"" + key + "\": ") + key.size() + 4)); };
    EXPECT_GE(number("seconds_slabs"), 0.0);
    EXPECT_GE(number("seconds_final"), 0.0);
    EXPECT_LE(number("seconds_slabs") + number("seconds_final"), number("seconds"));
    // The PLY header states the counts the report gives.
    const std::string ply = slurp(d + "/sphere.ply");
    const auto fo = json.find("\"faces_out\": ");
    const std::string faces = json.substr(fo + 13, json.find(',', fo) - fo - 13);
    EXPECT_NE(ply.find("element face " + faces + "\n"), std::string::npos);
    // --trace: a header and one row per decimation the report counts.
    ASSERT_EQ(run(d, "sphere.vdb -r 0.1 -b 1000 -q --trace trace.csv --report r2.json -o t.ply").code, 0);
    const std::string csv = slurp(d + "/trace.csv"), r2 = slurp(d + "/r2.json");
    const auto dp = r2.find("\"decimations\": ");
    const long decimations = std::stol(r2.substr(dp + 15));
    EXPECT_GT(decimations, 2);
    EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), decimations + 1);
    EXPECT_EQ(csv.rfind("decimation,faces_generated,faces_before,faces_after,uncontractible,target,slab\n", 0), 0u);
    // --quiet prints nothing on success.
    EXPECT_EQ(run(d, "sphere.vdb -q -o q.ply").err, "");
}

TEST(Cli, SameBytesForOneAndTwoThreads)
{
    const auto d = freshDir("threads");
    vt::GridSpec spec;
    spec.levelSet = false;
    spec.seed = 5;
    openvdb::io::File(d + "/fog.vdb").write({vt::randomSparseGrid(spec)});
    ASSERT_EQ(run(d, "fog.vdb --iso 0.5 --ratio 0.1 --batch 5000 --threads 1 -o one.ply").code, 0);
    ASSERT_EQ(run(d, "fog.vdb --iso 0.5 --ratio 0.1 --batch 5000 --threads 2 -o two.ply").code, 0);
    const std::string a = slurp(d + "/one.ply"), b = slurp(d + "/two.ply");
    EXPECT_GT(a.size(), 10000u);
    EXPECT_TRUE(a == b) << "outputs differ between 1 and 2 threads";
}

TEST(Cli, HelpExplainsEveryOption)
{
    const auto d = freshDir("help");
    const std::string cmd = std::string("'") + VDB_ISOSIMP_EXE + "' --help > '" + d + "/help.txt'";
    ASSERT_EQ(std::system(cmd.c_str()), 0);
    const std::string help = slurp(d + "/help.txt");
    for (const char* opt : {"--output", "--grid", "--iso", "--ratio", "--faces", "--batch", "--threads", "--report", "--trace", "--quiet"})
        EXPECT_NE(help.find(opt), std::string::npos) << opt;
}

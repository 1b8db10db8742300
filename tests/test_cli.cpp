// The vdb_isosimp program as a user meets it: bad input gives one clear line on stderr, a non-zero
// exit code and no output file; good input gives the mesh, the summary and the JSON report, byte for
// byte the same for any thread count.
#include "test_grids.h"
#include "mesh_io.h"
#include "mesh_stats.h"
#include "surface_checks.h"
#include "vdb_isosimp/frame_sequence.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <openvdb/tools/Composite.h>

#include "test_files.h"
#include "test_volumes.h"

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
    // The final pass's zero-area scan (it runs, the surface is decimated) and the output mesh's collection are a part of that pass.
    EXPECT_GT(number("seconds_final_parallel"), 0.0);
    EXPECT_LE(number("seconds_final_parallel"), number("seconds_final"));
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
    for (const char* opt : {"--output", "--grid", "--iso", "--ratio", "--faces", "--batch", "--threads", "--report", "--trace", "--quiet",
                            "--frames", "--min-component", "smoke.####.vdb", "density"})
        EXPECT_NE(help.find(opt), std::string::npos) << opt;
}

// Issue 17: which grid a file is meshed by default, frame sequences and floater pruning.
namespace {

// A small level-set sphere named `name` (class `levelSet`, else the same values as a fog-like grid).
openvdb::FloatGrid::Ptr namedSphere(const std::string& name, bool levelSet, float radius = 6.0f)
{
    openvdb::initialize();
    auto g = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(radius, openvdb::Vec3f(0), 0.5f);
    g->setName(name);
    if (!levelSet) g->setGridClass(openvdb::GRID_FOG_VOLUME);
    return g;
}

// Removes the meshes and reports of earlier runs, before runs that must leave none.
void removeOutputs(const std::string& dir)
{
    std::system(("cd '" + dir + "' && rm -f *.ply *.json").c_str());
}

// A text value of a JSON report.
std::string reportText(const std::string& json, const std::string& key)
{
    const auto at = json.find("\"" + key + "\": \"");
    if (at == std::string::npos) return "";
    const auto start = at + key.size() + 5;
    return json.substr(start, json.find('"', start) - start);
}

uint64_t reportInteger(const std::string& json, const std::string& key)
{
    const auto at = json.find("\"" + key + "\": ");
    return at == std::string::npos ? UINT64_MAX : std::stoull(json.substr(at + key.size() + 4));
}

// What stopped the decimation, said in the report and, for a face target the surface's topology cannot
// reach, in the summary: the integer CT volume (voxels exactly at the iso-value) is a sponge of many
// handles, met as far as it can be, with the genus the mesh's Euler characteristic gives; a sphere reaches
// the same target and says nothing; an error bound tighter than the target stops first and says nothing
// beyond its report; a chain says it per level.
TEST(Cli, WhatStoppedTheDecimationIsSaid)
{
    const auto d = freshDir("stopped_by");
    const vdb_isosimp::volumes::TestVolume ct = vdb_isosimp::volumes::makeVolume("ct-int", 64);
    openvdb::io::File(d + "/ct.vdb").write({ct.grid});
    sphere(d);
    const RunResult stuck = run(d, "ct.vdb --iso 100 -f 8 -o ct.ply --report ct.json");
    ASSERT_EQ(stuck.code, 0) << stuck.err;
    EXPECT_EQ(reportText(slurp(d + "/ct.json"), "stopped_by"), "topology");
    const vdb_isosimp::Mesh least = vdb_isosimp::eval::readMesh(d + "/ct.ply");
    const vdb_isosimp::eval::MeshStats s = vdb_isosimp::eval::computeMeshStats(least);
    ASSERT_GT(s.faces, 16u) << "the volume has no handles to keep";
    vt::expectClosedOutward(least, false, "ct-int at its least faces");
    const long long genus = 1 - s.eulerCharacteristic / 2;
    const std::string note = std::to_string(s.faces) + " faces, not the 8 asked for: the surface has genus " + std::to_string(genus) +
                             " or more (Euler characteristic " + std::to_string(s.eulerCharacteristic) + ")";
    EXPECT_NE(stuck.err.find(note), std::string::npos) << stuck.err;
    EXPECT_EQ(run(d, "ct.vdb --iso 100 -f 8 -q -o ct.ply").err, "");

    const RunResult reached = run(d, "sphere.vdb -f 8 -o s.ply --report s.json");
    ASSERT_EQ(reached.code, 0) << reached.err;
    EXPECT_EQ(reportText(slurp(d + "/s.json"), "stopped_by"), "target");
    EXPECT_LE(reportInteger(slurp(d + "/s.json"), "faces_out"), 10u);
    EXPECT_EQ(std::count(reached.err.begin(), reached.err.end(), '\n'), 1) << reached.err;

    const RunResult bounded = run(d, "sphere.vdb -f 8 --max-error 0.05 -o b.ply --report b.json");
    ASSERT_EQ(bounded.code, 0) << bounded.err;
    EXPECT_EQ(reportText(slurp(d + "/b.json"), "stopped_by"), "error bound");
    EXPECT_GT(reportInteger(slurp(d + "/b.json"), "faces_out"), 10u);
    EXPECT_EQ(bounded.err.find("asked for"), std::string::npos) << bounded.err;
    ASSERT_EQ(run(d, "sphere.vdb --max-error 0.05 -q -o b.ply --report b.json").code, 0);
    EXPECT_EQ(reportText(slurp(d + "/b.json"), "stopped_by"), "error bound");

    const RunResult loose = run(d, "ct.vdb --iso 100 -f 8 --max-error 1000 -o ct.ply --report ct.json");
    ASSERT_EQ(loose.code, 0) << loose.err;
    EXPECT_EQ(reportText(slurp(d + "/ct.json"), "stopped_by"), "topology");
    EXPECT_NE(loose.err.find("faces, not the 8 asked for: the surface has"), std::string::npos) << loose.err;
    const RunResult tetrahedron = run(d, "sphere.vdb --max-error 1000 -o s.ply --report s.json");
    ASSERT_EQ(tetrahedron.code, 0) << tetrahedron.err;
    EXPECT_EQ(reportText(slurp(d + "/s.json"), "stopped_by"), "topology");
    EXPECT_EQ(reportInteger(slurp(d + "/s.json"), "faces_out"), 4u) << "a tetrahedron: the least closed surface";
    EXPECT_EQ(tetrahedron.err.find("asked for"), std::string::npos) << tetrahedron.err;

    ASSERT_EQ(run(d, "ct.vdb --iso 100 --lods 0.5,0.0002 -q -o chain.ply --report chain.json").code, 0);
    const std::string chain = slurp(d + "/chain.json");
    EXPECT_EQ(reportText(chain, "lod0_stopped_by"), "target");
    EXPECT_EQ(reportText(chain, "lod1_stopped_by"), "topology");
    EXPECT_EQ(reportText(chain, "stopped_by"), "topology");
}

// A 5-frame sequence f.0001.vdb ... f.0005.vdb of fog spheres growing frame by frame.
void writeSequence(const std::string& dir, const std::vector<int>& frames)
{
    for (int f : frames) {
        char name[32];
        std::snprintf(name, sizeof name, "/f.%04d.vdb", f);
        openvdb::io::File(dir + name).write({namedSphere("density", false, 5.0f + float(f))});
    }
}

} // namespace

TEST(CliDefaultGrid, DensityBeforeAnEarlierColourChannel)
{
    const auto d = freshDir("default_density");
    auto colour = namedSphere("color.x", false);
    auto density = namedSphere("density", false, 8.0f);
    openvdb::io::File(d + "/smoke.vdb").write({colour, density});
    const RunResult r = run(d, "smoke.vdb --report r.json -o out.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(reportText(slurp(d + "/r.json"), "grid"), "density");
    EXPECT_NE(r.err.find("grid 'density'"), std::string::npos) << "the summary names the grid: " << r.err;
}

TEST(CliDefaultGrid, LevelSetBeforeAnEarlierFog)
{
    const auto d = freshDir("default_levelset");
    openvdb::io::File(d + "/both.vdb").write({namedSphere("density", false), namedSphere("surface", true, 8.0f)});
    const RunResult r = run(d, "both.vdb --report r.json -o out.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    const std::string json = slurp(d + "/r.json");
    EXPECT_EQ(reportText(json, "grid"), "surface");
    EXPECT_EQ(reportText(json, "grid_class"), "level set");
}

TEST(CliDefaultGrid, OnlyGridWhateverItsName)
{
    const auto d = freshDir("default_only");
    auto vel = openvdb::Vec3SGrid::create();
    vel->setName("vel");
    vel->tree().setValue(openvdb::Coord(0), openvdb::Vec3s(1, 0, 0));
    openvdb::io::File(d + "/t.vdb").write({vel, namedSphere("temperature", false)});
    const RunResult r = run(d, "t.vdb --report r.json -o out.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(reportText(slurp(d + "/r.json"), "grid"), "temperature");
    removeOutputs(d);
    // Naming the vector grid: one line saying which grids can be meshed.
    expectCleanFailure(run(d, "t.vdb --grid vel -o out.ply"), 1,
                       "t.vdb: grid 'vel' has value type vec3s; only float and double grids can be meshed (float/double grids: temperature)", d);
    expectCleanFailure(run(d, "t.vdb --grid density -o out.ply"), 1, "t.vdb: no grid named 'density' (grids: ", d);
}

TEST(CliFrames, SequenceWritesAMeshAndAReportPerFrame)
{
    const auto d = freshDir("frames");
    writeSequence(d, {1, 2, 3, 4, 5});
    const RunResult r = run(d, "f.####.vdb -o m.####.ply --report r.####.json");
    ASSERT_EQ(r.code, 0) << r.err;
    std::string isoOfFrame1;
    for (int f = 1; f <= 5; ++f) {
        char mesh[32], report[32];
        std::snprintf(mesh, sizeof mesh, "/m.%04d.ply", f);
        std::snprintf(report, sizeof report, "/r.%04d.json", f);
        EXPECT_TRUE(exists(d + mesh)) << mesh;
        const std::string json = slurp(d + report);
        EXPECT_NE(json.find(std::string("\"output\": \"m.") + (mesh + 3)), std::string::npos) << json;
        // One iso-value for every frame: the first frame's default.
        const std::string iso = json.substr(json.find("\"iso\": "), 25);
        if (f == 1) isoOfFrame1 = iso;
        EXPECT_EQ(iso, isoOfFrame1) << "frame " << f;
    }
    EXPECT_NE(r.err.find("from frame 1, used for every frame"), std::string::npos) << r.err;
    for (int f = 1; f <= 5; ++f) EXPECT_NE(r.err.find("f.000" + std::to_string(f) + ".vdb, grid 'density'"), std::string::npos) << r.err;
    // A printf pattern names the same files; --frames picks a range.
    ASSERT_EQ(run(d, "f.%04d.vdb -o p.%d.ply --frames 2-3 -q").code, 0);
    EXPECT_TRUE(exists(d + "/p.2.ply") && exists(d + "/p.3.ply"));
    EXPECT_FALSE(exists(d + "/p.1.ply") || exists(d + "/p.4.ply"));
    EXPECT_EQ(slurp(d + "/p.2.ply"), slurp(d + "/m.0002.ply"));
}

TEST(CliFrames, MissingFrameIsOneLineAndTheOthersStillRun)
{
    const auto d = freshDir("frames_missing");
    writeSequence(d, {1, 2, 4, 5});
    const RunResult r = run(d, "f.%04d.vdb -o m.%04d.ply --frames 1-5 -q");
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_EQ(r.err, "vdb_isosimp: frame 3: f.0003.vdb: cannot open file for reading (missing or unreadable)\n");
    for (int f : {1, 2, 4, 5}) EXPECT_TRUE(exists(d + "/m.000" + std::to_string(f) + ".ply")) << f;
    EXPECT_FALSE(exists(d + "/m.0003.ply"));
    // A damaged frame too.
    std::ofstream(d + "/f.0003.vdb") << "not a volume";
    const RunResult damaged = run(d, "f.%04d.vdb -o n.%04d.ply -q");
    EXPECT_EQ(damaged.code, 1);
    EXPECT_EQ(std::count(damaged.err.begin(), damaged.err.end(), '\n'), 1) << damaged.err;
    EXPECT_NE(damaged.err.find("frame 3: f.0003.vdb: not a readable OpenVDB file"), std::string::npos) << damaged.err;
    EXPECT_TRUE(exists(d + "/n.0005.ply"));
}

TEST(CliFrames, PatternOnOneSideOnlyIsAUsageError)
{
    const auto d = freshDir("frames_usage");
    writeSequence(d, {1, 2});
    const struct {
        const char* args;
        int code;
        const char* says;
    } cases[] = {
        {"f.####.vdb -o m.ply", 2, "-o needs a frame pattern too"},
        {"f.0001.vdb -o m.####.ply", 2, "names a frame sequence but the input 'f.0001.vdb' does not"},
        {"f.####.vdb -o m.####.ply --report r.json", 2, "--report 'r.json'"},
        {"f.0001.vdb -o m.ply --frames 1-2", 2, "--frames: 'f.0001.vdb' is not a frame sequence"},
        {"f.####.vdb -o m.####.ply --frames 2-1", 2, "--frames: '2-1'"},
        {"f.####.vdb -o m.####.ply --frames x", 2, "--frames: 'x'"},
        {"g.####.vdb -o m.####.ply", 1, "g.####.vdb: no file matches the frame pattern"},
    };
    for (const auto& c : cases) expectCleanFailure(run(d, c.args), c.code, c.says, d);
}

TEST(CliPrune, MinComponentKeepsTheBigSphereOnly)
{
    const auto d = freshDir("prune");
    openvdb::initialize();
    auto big = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(20.0f, openvdb::Vec3f(0), 0.5f, 3.0f);
    const openvdb::Vec3f centres[] = {{40, 0, 0}, {-40, 0, 0}, {0, 40, 0}, {0, 0, -40}};
    for (const auto& c : centres)
        openvdb::tools::csgUnion(*big, *openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(2.5f, c, 0.5f, 3.0f));
    big->setName("spheres");
    openvdb::io::File(d + "/spheres.vdb").write({big});
    // Areas: the big sphere about 4 pi 20^2 = 5027, the small ones about 79.
    ASSERT_EQ(run(d, "spheres.vdb -q -o all.ply --report all.json").code, 0);
    const RunResult r = run(d, "spheres.vdb -q --min-component 500 -o big.ply --report big.json");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(reportInteger(slurp(d + "/all.json"), "components_pruned"), 0u);
    EXPECT_EQ(reportInteger(slurp(d + "/big.json"), "components_pruned"), 4u);
    const vdb_isosimp::Mesh all = vdb_isosimp::eval::readMesh(d + "/all.ply"), kept = vdb_isosimp::eval::readMesh(d + "/big.ply");
    EXPECT_EQ(vdb_isosimp::eval::computeMeshStats(all).components, 5u);
    const vdb_isosimp::eval::MeshStats s = vdb_isosimp::eval::computeMeshStats(kept);
    EXPECT_EQ(s.components, 1u);
    EXPECT_GT(s.area, 4500.0);
    EXPECT_EQ(s.eulerCharacteristic, 2);
    vt::expectClosedOutward(kept, false, "pruned");
    removeOutputs(d);
    // Bad values are usage errors; a minimum above every component leaves no surface.
    for (const char* bad : {"0", "-1", "x", "nan"})
        expectCleanFailure(run(d, std::string("spheres.vdb --min-component ") + bad + " -o bad.ply"), 2, "--min-component", d);
    expectCleanFailure(run(d, "spheres.vdb --min-component 1e6 -o bad.ply"), 3, "every component of the surface in grid 'spheres' has an area below 1e+06", d);
}

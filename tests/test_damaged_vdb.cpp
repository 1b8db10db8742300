// Damaged .vdb files: the program never crashes, hangs or prints a raw exception; every error is one
// line naming the file, and nothing is left under the output name.
//
// Mutations: each sample of fuzz/vdb_samples.h (blosc, zip, none, half floats, several grids, level
// sets and fog) is damaged deterministically at positions spread over the whole file (header,
// metadata, topology, leaf data) in five ways a bad disk, an interrupted copy or a broken writer
// leave: one byte, four bytes, eight 0xFF bytes, sixteen zero bytes, and a cut. Each damaged file is
// run through the program under an address-space limit (a file that makes OpenVDB allocate what it
// states fails instead of swapping the machine) and a time limit.
// Located damage: the leaf a damaged chunk belongs to is found independently of the reader, as the
// bytes where two files differ that differ only in that leaf's voxels; the message must name it.
#include "vdb/input_checks.h"
#include "vdb/volume_reader.h"
#include "vdb_isosimp/errors.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include "fuzz/vdb_samples.h"
#include "test_files.h"

#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <fcntl.h>
#include <fstream>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace {

using vdb_isosimp::testing::exists;
using vdb_isosimp::testing::slurp;

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAsan = true;  // ASan reserves terabytes of address space: no RLIMIT_AS then
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAsan = true;
#else
constexpr bool kAsan = false;
#endif
#else
constexpr bool kAsan = false;
#endif

constexpr rlim_t kAddressSpace = rlim_t(3) << 30;  // far above what these small files need
// A hang, not a slow run: under ASan the two runs of the 40,000-leaf row file take 23 s together on an
// idle 2-core machine, and one of them passed 60 s while both cores were busy with other work.
constexpr int kTimeoutSeconds = kAsan ? 180 : 60;

std::string scratch(const std::string& name)
{
    const std::string d = ::testing::TempDir() + "/damaged_" + name;
    std::system(("rm -rf '" + d + "' && mkdir -p '" + d + "'").c_str());
    return d;
}

struct Outcome {
    int code = 0;         // exit code; -signal for a signal death; -1000 for a hang
    std::string err;      // stderr
};

// Runs the program on dir/in.vdb with output dir/out.ply, under the limits above.
Outcome runLimited(const std::string& dir, const std::vector<std::string>& extra = {})
{
    const pid_t pid = ::fork();
    if (pid == 0) {
        if (!kAsan) {
            const rlimit as{kAddressSpace, kAddressSpace};
            ::setrlimit(RLIMIT_AS, &as);
        }
        const int err = ::open((dir + "/stderr.log").c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        const int null = ::open("/dev/null", O_WRONLY);
        if (err < 0 || null < 0 || ::chdir(dir.c_str()) != 0) ::_exit(120);
        ::dup2(err, 2);
        ::dup2(null, 1);
        std::vector<std::string> args = {VDB_ISOSIMP_EXE, "in.vdb", "-q", "-o", "out.ply"};
        args.insert(args.end(), extra.begin(), extra.end());
        std::vector<char*> a;
        for (auto& s : args) a.push_back(&s[0]);
        a.push_back(nullptr);
        ::execv(a[0], a.data());
        ::_exit(121);
    }
    Outcome o;
    int status = 0;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(kTimeoutSeconds);
    for (;;) {
        const pid_t r = ::waitpid(pid, &status, WNOHANG);
        if (r == pid) break;
        if (std::chrono::steady_clock::now() > deadline) {
            ::kill(pid, SIGKILL);
            ::waitpid(pid, &status, 0);
            o.code = -1000;
            return o;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    o.code = WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
    o.err = slurp(dir + "/stderr.log");
    return o;
}

// What a failed run must look like: one line, "vdb_isosimp: in.vdb: ...", in our words.
std::string badMessage(const std::string& err)
{
    if (std::count(err.begin(), err.end(), '\n') != 1 || err.back() != '\n') return "not one line";
    if (err.rfind("vdb_isosimp: in.vdb: ", 0) != 0) return "does not name the file";
    for (const char* raw : {"std::", "bad_alloc", "terminate", "Error: ", "Exception", "what()", "Sanitizer",
                            "runtime error", "Aborted"})
        if (err.find(raw) != std::string::npos) return std::string("raw text '") + raw + "'";
    return "";
}

// Deterministic damage number `i` of `n` to `bytes`: the position walks the whole file (one case per
// n-th of it, jittered), the kind cycles through the five.
std::string damage(const std::string& bytes, int i, int n)
{
    uint64_t h = 0x9E3779B97F4A7C15ull * uint64_t(i + 1);
    h ^= h >> 29;
    const size_t size = bytes.size();
    const size_t span = std::max<size_t>(1, size / size_t(n));
    const size_t pos = std::min(size - 1, size_t(i) * size / size_t(n) + size_t(h % span));
    std::string d = bytes;
    switch (i % 5) {
    case 0: d[pos] = char(uint8_t(d[pos]) ^ uint8_t(1 + (h >> 8) % 255)); break;
    case 1:
        for (size_t k = 0; k < 4 && pos + k < size; ++k) d[pos + k] = char(h >> (8 * k + 16));
        break;
    case 2:
        for (size_t k = 0; k < 8 && pos + k < size; ++k) d[pos + k] = char(0xFF);
        break;
    case 3:
        for (size_t k = 0; k < 16 && pos + k < size; ++k) d[pos + k] = 0;
        break;
    default: d.resize(pos); break;
    }
    return d;
}

void writeBytes(const std::string& path, const std::string& bytes)
{
    std::ofstream(path, std::ios::binary | std::ios::trunc).write(bytes.data(), std::streamsize(bytes.size()));
}

constexpr int kCasesPerSample = 36;  // 11 samples: 396 damaged files

class Mutations : public ::testing::TestWithParam<vdb_samples::Sample> {};

TEST_P(Mutations, NeverCrashHangOrRawMessage)
{
    const vdb_samples::Sample& sample = GetParam();
    const std::string d = scratch(sample.name);
    sample.write(d + "/whole.vdb");
    const std::string whole = slurp(d + "/whole.vdb");
    ASSERT_GT(whole.size(), 200u);
    // The undamaged file meshes.
    writeBytes(d + "/in.vdb", whole);
    const Outcome clean = runLimited(d);
    ASSERT_EQ(clean.code, 0) << clean.err;
    std::remove((d + "/out.ply").c_str());

    int errors = 0, meshes = 0;
    for (int i = 0; i < kCasesPerSample; ++i) {
        writeBytes(d + "/in.vdb", damage(whole, i, kCasesPerSample));
        const Outcome o = runLimited(d);
        const std::string what = sample.name + " case " + std::to_string(i) + " (kind " + std::to_string(i % 5) + ")";
        ASSERT_NE(o.code, -1000) << what << ": hang (over " << kTimeoutSeconds << " s)";
        ASSERT_GE(o.code, 0) << what << ": killed by signal " << -o.code << "\n" << o.err;
        ASSERT_TRUE(o.code == 0 || o.code == 1 || o.code == 3) << what << ": exit " << o.code << "\n" << o.err;
        if (o.code == 0) {
            EXPECT_EQ(o.err, "") << what;
            EXPECT_TRUE(exists(d + "/out.ply")) << what;
            ++meshes;
        } else {
            EXPECT_EQ(badMessage(o.err), "") << what << ": " << o.err;
            EXPECT_FALSE(exists(d + "/out.ply")) << what << ": a failed run left its output";
            errors += o.code == 1;
        }
        std::remove((d + "/out.ply").c_str());
        // Only the input, the log and the undamaged copy: no temporary left behind.
        std::string left;
        FILE* p = popen(("ls -A '" + d + "'").c_str(), "r");
        char buf[256];
        while (p && fgets(buf, sizeof buf, p)) left += buf;
        if (p) pclose(p);
        EXPECT_EQ(left, "in.vdb\nstderr.log\nwhole.vdb\n") << what;
    }
    // Most damage is found: a test that damaged nothing the reader reads would pass vacuously.
    EXPECT_GE(errors, kCasesPerSample / 3) << sample.name << ": " << errors << " errors, " << meshes << " meshes";
    std::printf("%s: %d cases, %d refused, %d meshed\n", sample.name.c_str(), kCasesPerSample, errors, meshes);
}

INSTANTIATE_TEST_SUITE_P(DamagedVdb, Mutations, ::testing::ValuesIn(vdb_samples::samples()),
                         [](const ::testing::TestParamInfo<vdb_samples::Sample>& i) { return i.param.name; });

// ---------------------------------------------------------------------------------------------
// Layouts OpenVDB reads without offsets to check against

// A stream (no grid offsets) is walked grid by grid before OpenVDB reads it whole: undamaged, it
// meshes exactly as the same grid written as a file.
TEST(DamagedVdb, StreamMeshesAsTheFile)
{
    const std::string d = scratch("stream_clean");
    const uint32_t blosc = openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK;
    auto temperature = vdb_samples::half<openvdb::FloatGrid>(vdb_samples::fog());
    temperature->setName("temperature");
    std::string meshes[2];
    for (int stream = 0; stream < 2; ++stream) {
        const openvdb::GridPtrVec grids = {vdb_samples::sphere(4.0f), temperature, vdb_samples::fog()};
        if (stream) vdb_samples::writeStream(d + "/in.vdb", grids, blosc);
        else vdb_samples::write(d + "/in.vdb", grids, blosc);
        const Outcome o = runLimited(d, {"--grid", "density"});
        ASSERT_EQ(o.code, 0) << o.err;
        meshes[stream] = slurp(d + "/out.ply");
    }
    EXPECT_GT(meshes[0].size(), 1000u);
    EXPECT_EQ(meshes[0], meshes[1]);
}

TEST(DamagedVdb, StreamWithAGridTheWalkDoesNotKnowIsRefused)
{
    const std::string d = scratch("stream_vector");
    auto vel = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
    vel->setName("vel");
    vel->tree().setValue(openvdb::Coord(1, 2, 3), openvdb::Vec3s(1.0f, 0.0f, 0.0f));
    vdb_samples::writeStream(d + "/in.vdb", {vdb_samples::fog(), vel}, openvdb::io::COMPRESS_BLOSC);
    const Outcome o = runLimited(d);
    EXPECT_EQ(o.code, 1) << o.err;
    EXPECT_EQ(badMessage(o.err), "") << o.err;
    EXPECT_NE(o.err.find("grid 'vel' of a file written without grid offsets (as a stream) is of type Tree_vec3s_5_4_3"),
              std::string::npos)
        << o.err;
    EXPECT_FALSE(exists(d + "/out.ply"));
}

TEST(DamagedVdb, FormatsOlderThanTheWalkAreRefused)
{
    const std::string d = scratch("old_format");
    vdb_samples::write(d + "/whole.vdb", {vdb_samples::fog()}, openvdb::io::COMPRESS_BLOSC);
    std::string bytes = slurp(d + "/whole.vdb");
    const uint32_t old = openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION - 1;
    bytes.replace(8, 4, reinterpret_cast<const char*>(&old), 4);
    writeBytes(d + "/in.vdb", bytes);
    const Outcome o = runLimited(d);
    EXPECT_EQ(o.code, 1) << o.err;
    EXPECT_EQ(badMessage(o.err), "") << o.err;
    EXPECT_NE(o.err.find("OpenVDB file format 221 is older than format 222"), std::string::npos) << o.err;
    EXPECT_FALSE(exists(d + "/out.ply"));
}

// OpenVDB reads a topology as half floats when the grid's metadata says so, the walk when its type
// does: a file where they differ (a renamed item, a false flag) is refused before OpenVDB reads it one
// way and fails (leaking the node it was filling) or reads it the other way unchecked.
TEST(DamagedVdb, HalfFloatMetadataThatDisagreesWithTheTypeIsRefused)
{
    const std::string d = scratch("half_meta");
    const uint32_t zip = openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK;
    vdb_samples::write(d + "/whole.vdb", {vdb_samples::half<openvdb::FloatGrid>(vdb_samples::fog())}, zip);
    const std::string whole = slurp(d + "/whole.vdb");
    const std::string key = openvdb::GridBase::META_SAVE_HALF_FLOAT;
    const size_t at = whole.find(key);
    ASSERT_NE(at, std::string::npos);
    // After the name: the type name "bool" (length-prefixed), the value's size (1), the value.
    const size_t value = at + key.size() + 4 + 4 + 4;
    ASSERT_EQ(whole.substr(at + key.size() + 4, 4), "bool");
    ASSERT_EQ(whole[value], 1);
    for (int renamed = 0; renamed < 2; ++renamed) {
        std::string bytes = whole;
        if (renamed) bytes[at + key.size() - 1] = 'T';
        else bytes[value] = 0;
        writeBytes(d + "/in.vdb", bytes);
        const Outcome o = runLimited(d);
        EXPECT_EQ(o.code, 1) << o.err;
        EXPECT_EQ(badMessage(o.err), "") << o.err;
        EXPECT_NE(o.err.find("its metadata 'is_saved_as_half_float' disagrees with its type Tree_float_5_4_3_HalfFloat"),
                  std::string::npos)
            << (renamed ? "renamed: " : "false: ") << o.err;
        EXPECT_FALSE(exists(d + "/out.ply"));
    }
    writeBytes(d + "/in.vdb", whole);
    const Outcome o = runLimited(d);
    EXPECT_EQ(o.code, 0) << o.err;
}

// ---------------------------------------------------------------------------------------------
// Located damage

// A fog grid with a dense 24^3 block (27 leaves); `marked` changes the voxels of leaf [8, 8, 8] only.
openvdb::FloatGrid::Ptr blockGrid(bool marked, openvdb::GridClass cls)
{
    auto g = openvdb::FloatGrid::create(0.0f);
    g->setName("density");
    g->setGridClass(cls);
    auto acc = g->getAccessor();
    for (int z = 0; z < 24; ++z)
        for (int y = 0; y < 24; ++y)
            for (int x = 0; x < 24; ++x) {
                const bool inLeaf = x >= 8 && x < 16 && y >= 8 && y < 16 && z >= 8 && z < 16;
                float v = float(((x * 7 + y * 13 + z * 29) % 31)) / 31.0f;
                if (marked && inLeaf) v = 1.0f - v * 0.5f;
                acc.setValueOn(openvdb::Coord(x, y, z), v);
            }
    return g;
}

// One past the last byte where two files differ, counted from their ends.
size_t differingEnd(const std::string& a, const std::string& b)
{
    size_t ea = a.size(), eb = b.size();
    while (ea > 0 && eb > 0 && a[ea - 1] == b[eb - 1]) --ea, --eb;
    return ea;
}

struct Located {
    std::string name;
    uint32_t compression;
    openvdb::GridClass cls;
    bool half;
};

class LocatedDamage : public ::testing::TestWithParam<Located> {};

TEST_P(LocatedDamage, NamesTheLeafInProgramLibraryAndPython)
{
    const Located& c = GetParam();
    const std::string d = scratch("located_" + c.name);
    auto a = blockGrid(false, c.cls), b = blockGrid(true, c.cls);
    a->setSaveFloatAsHalf(c.half);
    b->setSaveFloatAsHalf(c.half);
    vdb_samples::write(d + "/a.vdb", {a}, c.compression);
    vdb_samples::write(d + "/b.vdb", {b}, c.compression);
    const std::string fa = slurp(d + "/a.vdb"), fb = slurp(d + "/b.vdb");
    // Everything after the marked leaf's record is the same in both files (the header differs too:
    // a fresh UUID, and the offsets when the chunk's size changed), so the last differing byte lies
    // in that record's values: scramble the bytes before it.
    const size_t end = differingEnd(fa, fb);
    ASSERT_GT(end, 100u);
    std::string bad = fa;
    const bool compressed = c.compression & (openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ZIP);
    for (size_t k = end - 24; k < end; ++k) bad[k] = compressed ? char(0xA5 ^ (k * 37)) : char(0xFF);
    writeBytes(d + "/in.vdb", bad);

    const Outcome o = runLimited(d);
    ASSERT_EQ(o.code, 1) << o.err;
    EXPECT_EQ(badMessage(o.err), "") << o.err;
    const std::string expected = compressed ? "vdb_isosimp: in.vdb: grid 'density', leaf [8, 8, 8]: compressed data is damaged"
                                            : "vdb_isosimp: in.vdb: voxel [";
    EXPECT_EQ(o.err.rfind(expected, 0), 0u) << o.err;
    if (!compressed) {  // raw values: the scrambled ones are read as values, and some are NaN
        EXPECT_NE(o.err.find("nan (NaN/Inf values are not allowed)"), std::string::npos) << o.err;
        const size_t at = o.err.find("voxel [") + 7;
        int x = -1, y = -1, z = -1;
        ASSERT_EQ(std::sscanf(o.err.c_str() + at, "%d, %d, %d", &x, &y, &z), 3) << o.err;
        EXPECT_TRUE(x >= 8 && x < 16 && y >= 8 && y < 16 && z >= 8 && z < 16) << o.err;
    }
    EXPECT_FALSE(exists(d + "/out.ply"));

    // The library throws InputError with the same text.
    vdb_isosimp::Options opt;
    std::string libraryMessage;
    try {
        vdb_isosimp::simplifyFile(d + "/in.vdb", opt);
    } catch (const vdb_isosimp::InputError& e) {
        libraryMessage = e.what();
    }
    EXPECT_EQ("vdb_isosimp: " + libraryMessage + "\n", std::string(o.err).replace(13, 6, d + "/in.vdb"))
        << "library: " << libraryMessage;

    // Python raises InputError with the same text (when the module is built).
    const std::string module = VDB_ISOSIMP_PYTHON_DIR;
    if (!kAsan && !module.empty() && std::system(("ls '" + module + "'/vdb_isosimp*.so > /dev/null 2>&1").c_str()) == 0) {
        const std::string script = d + "/check.py";
        std::ofstream(script) << "import vdb_isosimp, sys\n"
                                 "try:\n"
                                 "    vdb_isosimp.simplify(sys.argv[1])\n"
                                 "    print('no error')\n"
                                 "except vdb_isosimp.InputError as e:\n"
                                 "    print('InputError: ' + str(e))\n";
        const std::string cmd = "cd '" + d + "' && PYTHONPATH='" + module + "' /usr/bin/python3 check.py '" + d +
                                "/in.vdb' > py.log 2>&1";
        EXPECT_EQ(std::system(cmd.c_str()), 0) << slurp(d + "/py.log");
        EXPECT_EQ(slurp(d + "/py.log"), "InputError: " + libraryMessage + "\n");
    }
}

INSTANTIATE_TEST_SUITE_P(DamagedVdb, LocatedDamage,
                         ::testing::Values(Located{"blosc", openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK,
                                                   openvdb::GRID_FOG_VOLUME, false},
                                           Located{"blosc_half", openvdb::io::COMPRESS_BLOSC, openvdb::GRID_FOG_VOLUME, true},
                                           Located{"zip", openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK,
                                                   openvdb::GRID_UNKNOWN, false},
                                           Located{"none", openvdb::io::COMPRESS_NONE, openvdb::GRID_FOG_VOLUME, false}),
                         [](const ::testing::TestParamInfo<Located>& i) { return i.param.name; });

// A grid of 40,000 leaves in a row along x, two voxels each: the walk takes its leaf records in runs of
// at most 16,384 on all threads (from where the delayed-load metadata says each starts). A leaf damaged
// in the last run is named as in a file walked one record after another; the undamaged file meshes.
openvdb::FloatGrid::Ptr rowGrid(int marked)
{
    auto g = openvdb::FloatGrid::create(0.0f);
    g->setName("density");
    auto acc = g->getAccessor();
    for (int i = 0; i < 40000; ++i) {
        acc.setValueOn(openvdb::Coord(8 * i + 3, 2, 5), i == marked ? 0.75f : 1.0f);
        acc.setValueOn(openvdb::Coord(8 * i + 4, 2, 5), 0.25f + float(i % 7) / 8.0f);
    }
    return g;
}

// The row grid's file (a.vdb in `d`), and the same with the 12 bytes before the end of leaf 35,000's
// record scrambled (the last bytes where it differs from a file whose leaf 35,000 holds other values).
std::pair<std::string, std::string> rowFiles(const std::string& d)
{
    const uint32_t compression = openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK;
    vdb_samples::write(d + "/a.vdb", {rowGrid(-1)}, compression);
    vdb_samples::write(d + "/b.vdb", {rowGrid(35000)}, compression);
    const std::string fa = slurp(d + "/a.vdb"), fb = slurp(d + "/b.vdb");
    const size_t end = differingEnd(fa, fb);
    EXPECT_GT(end, fa.size() / 2);
    std::string bad = fa;
    for (size_t k = end - 12; k < end; ++k) bad[k] = char(0xA5 ^ (k * 37));
    return {fa, bad};
}

TEST(DamagedVdb, LocatedAmongLeavesWalkedInRuns)
{
    const std::string d = scratch("located_runs");
    const auto [fa, bad] = rowFiles(d);
    writeBytes(d + "/in.vdb", fa);
    const Outcome clean = runLimited(d);
    ASSERT_EQ(clean.code, 0) << clean.err;
    std::remove((d + "/out.ply").c_str());

    writeBytes(d + "/in.vdb", bad);
    const Outcome o = runLimited(d);
    ASSERT_EQ(o.code, 1) << o.err;
    EXPECT_EQ(badMessage(o.err), "") << o.err;
    // Found by the walk, before OpenVDB reads the file: the chunk's header states a size that is not the leaf's.
    EXPECT_EQ(o.err.rfind("vdb_isosimp: in.vdb: grid 'density', leaf [280000, 0, 0]: compressed data is damaged (blosc chunk", 0), 0u)
        << o.err;
    EXPECT_FALSE(exists(d + "/out.ply"));
}

// The processes of a distributed run each walk their own copy's records and agree on the stored tree's
// digest (VdbGridLayout::digest): the same grid written twice gives one digest, another tree another.
uint64_t digestOf(const std::string& path)
{
    const vdb_isosimp::VdbFileEntries entries = vdb_isosimp::checkVdbFileStructure(path);
    const vdb_isosimp::VdbGridLayout layout = vdb_isosimp::checkVdbGridData(path, entries, "density");
    EXPECT_TRUE(layout.checked);
    return layout.digest;
}

TEST(DamagedVdb, CopiesOfOneTreeHaveOneDigest)
{
    const std::string d = scratch("digest");
    const uint32_t compression = openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK;
    vdb_samples::write(d + "/a.vdb", {rowGrid(-1)}, compression);
    vdb_samples::write(d + "/again.vdb", {rowGrid(-1)}, compression);  // another file UUID, the same tree
    auto g = rowGrid(-1);
    g->tree().setValueOn(openvdb::Coord(3, 3, 5), 0.5f);  // one more active voxel in the first leaf
    vdb_samples::write(d + "/other.vdb", {g}, compression);
    vdb_samples::write(d + "/values.vdb", {rowGrid(35000)}, compression);  // one leaf's values: its chunk's size
    const uint64_t a = digestOf(d + "/a.vdb");
    EXPECT_NE(slurp(d + "/a.vdb"), slurp(d + "/again.vdb"));
    EXPECT_EQ(digestOf(d + "/again.vdb"), a);
    EXPECT_NE(digestOf(d + "/other.vdb"), a);
    if (slurp(d + "/values.vdb").size() != slurp(d + "/a.vdb").size()) {
        EXPECT_NE(digestOf(d + "/values.vdb"), a);
    }
}

TEST(DamagedVdb, EveryOpenAgreesOnce)
{
    // Whatever stops an open (a missing file, a cut file, a damaged leaf record) or not, a process
    // agrees once, with no say when its walk did not end: the others wait for every one of them.
    const std::string d = scratch("agree_once");
    const auto [fa, bad] = rowFiles(d);
    writeBytes(d + "/cut.vdb", fa.substr(0, fa.size() / 2));
    writeBytes(d + "/bad.vdb", bad);
    for (const std::string name : {"a.vdb", "missing.vdb", "cut.vdb", "bad.vdb"}) {
        int calls = 0;
        bool said = false;
        vdb_isosimp::TreeAgreement agreement;
        agreement.agree = [&](bool walked, bool sound, uint64_t) {
            ++calls;
            said = walked;
            return sound;
        };
        bool opened = false;
        std::string error;
        try {
            opened = vdb_isosimp::Volume::open(d + "/" + name, "", agreement) != nullptr;
        } catch (const vdb_isosimp::InputError& e) {
            error = e.what();
        }
        EXPECT_EQ(opened, name == "a.vdb") << error;
        EXPECT_EQ(calls, 1) << name;
        EXPECT_EQ(said, name == "a.vdb") << name;
        if (name == "bad.vdb") {
            EXPECT_NE(error.find("leaf [280000, 0, 0]: compressed data is damaged"), std::string::npos) << error;
        }
    }
    // An agreement that fails (the copies differ) fails the open, once.
    int calls = 0;
    vdb_isosimp::TreeAgreement differ;
    differ.agree = [&](bool, bool, uint64_t) -> bool {
        ++calls;
        throw vdb_isosimp::InputError("the copies differ");
    };
    EXPECT_THROW(vdb_isosimp::Volume::open(d + "/a.vdb", "", differ), vdb_isosimp::InputError);
    EXPECT_EQ(calls, 1);
    differ.parts = 2;  // the same where the walk is shared
    EXPECT_THROW(vdb_isosimp::Volume::open(d + "/a.vdb", "", differ), vdb_isosimp::InputError);
    EXPECT_EQ(calls, 2);
}

TEST(DamagedVdb, ASharedWalkLeavesNoReadLeafUnwalked)
{
    // Two processes share the walk of the row grid's 40,000 leaf records: part 0 walks the first
    // 20,000, part 1 the others, where leaf 35,000 (at x = 280000) is damaged in this copy.
    const std::string d = scratch("shared_walk");
    const auto [fa, bad] = rowFiles(d);
    writeBytes(d + "/bad.vdb", bad);
    const std::string damaged = "leaf [280000, 0, 0]: compressed data is damaged";
    const auto share = [](size_t part, bool othersSound, int& calls, bool& mineSound) {
        vdb_isosimp::TreeAgreement a;
        a.part = part;
        a.parts = 2;
        a.agree = [&calls, &mineSound, othersSound](bool walked, bool sound, uint64_t) {
            ++calls;
            mineSound = walked && sound;
            return mineSound && othersSound;
        };
        return a;
    };
    int calls = 0;
    bool sound = false;
    // Part 0 finds its part sound; the other process's part (its own copy) was sound too. The damaged
    // record is walked where this process comes to read it, and only there.
    {
        const auto a = share(0, true, calls, sound);
        auto v = vdb_isosimp::Volume::open(d + "/bad.vdb", "", a);
        EXPECT_EQ(calls, 1);
        EXPECT_TRUE(sound);
        EXPECT_NO_THROW(v->keepLeaves([](const std::array<int32_t, 3>& o) { return o[0] < 200000; }));
        vdb_isosimp::BlockSamples s;
        EXPECT_NO_THROW(v->sample({8, 0, 0}, s));
    }
    {
        const auto a = share(0, true, calls, sound);
        auto v = vdb_isosimp::Volume::open(d + "/bad.vdb", "", a);
        // The open read part 0's share of the topology; the blocks of both parts bring in the rest.
        const std::array<int32_t, 3> blocks[] = {{8, 0, 0}, {280000, 0, 0}};
        v->readAround(blocks, 2);
        try {
            v->keepLeaves({});  // every leaf it holds: the damaged one too
            ADD_FAILURE() << "the damaged record went unwalked";
        } catch (const vdb_isosimp::InputError& e) {
            EXPECT_NE(std::string(e.what()).find(damaged), std::string::npos) << e.what();
        }
    }
    // A value-range scan reads the leaves of the share of the topology the open read: here the walked
    // part's, whose records are sound.
    {
        const auto a = share(0, true, calls, sound);
        auto v = vdb_isosimp::Volume::open(d + "/bad.vdb", "", a);
        EXPECT_NO_THROW(v->valueRange(0, 2));
    }
    // Part 1 holds the damaged record: it says so, and every process walks every record, as one does.
    calls = 0;
    for (const bool othersSound : {true, false}) {
        const auto a = share(1, othersSound, calls, sound);
        try {
            vdb_isosimp::Volume::open(d + "/bad.vdb", "", a);
            ADD_FAILURE() << "opened";
        } catch (const vdb_isosimp::InputError& e) {
            EXPECT_NE(std::string(e.what()).find(damaged), std::string::npos) << e.what();
        }
        EXPECT_FALSE(sound);
    }
    EXPECT_EQ(calls, 2);
    // Part 0 whose partner found a fault walks every record itself.
    {
        const auto a = share(0, false, calls, sound);
        EXPECT_THROW(vdb_isosimp::Volume::open(d + "/bad.vdb", "", a), vdb_isosimp::InputError);
        EXPECT_TRUE(sound);
    }
}

// The grids' headers read from the bytes the walk found (readGridHeaders, which skips the delayed-load
// tables) are what OpenVDB's own listing gives: the same grids in the same order, each with the same
// name, type, class, half-float flag, transform and metadata.
void expectSameHeaders(const openvdb::GridPtrVec& ours, const openvdb::GridPtrVec& openvdbs, const std::string& what)
{
    ASSERT_EQ(ours.size(), openvdbs.size()) << what;
    for (size_t i = 0; i < ours.size(); ++i) {
        const openvdb::GridBase& a = *ours[i];
        const openvdb::GridBase& b = *openvdbs[i];
        EXPECT_EQ(a.getName(), b.getName()) << what << " grid " << i;
        EXPECT_EQ(a.type(), b.type()) << what << " grid " << i;
        EXPECT_EQ(a.getGridClass(), b.getGridClass()) << what << " grid " << i;
        EXPECT_EQ(a.saveFloatAsHalf(), b.saveFloatAsHalf()) << what << " grid " << i;
        EXPECT_TRUE(a.transform() == b.transform()) << what << " grid " << i;
        EXPECT_EQ(a.metaCount(), b.metaCount()) << what << " grid " << i;
        EXPECT_EQ(a.str(), b.str()) << what << " grid " << i;
        EXPECT_FALSE(a[openvdb::GridBase::META_FILE_DELAYED_LOAD]) << what << " grid " << i;
    }
}

openvdb::GridPtrVecPtr openvdbHeaders(const std::string& path)
{
    openvdb::io::File f(path);
    f.open(true);
    return f.readAllGridMetadata();
}

openvdb::GridPtrVecPtr ourHeaders(const std::string& path)
{
    const vdb_isosimp::VdbFileEntries entries = vdb_isosimp::checkVdbFileStructure(path);
    openvdb::io::File f(path);
    f.open(true);
    return vdb_isosimp::readGridHeaders(path, entries, f);
}

TEST(DamagedVdb, GridHeadersAreOpenVdbsWithoutTheDelayedLoadTables)
{
    openvdb::initialize();
    const std::string d = scratch("headers");
    for (const auto& s : vdb_samples::samples()) {
        const std::string path = d + "/" + s.name + ".vdb";
        s.write(path);
        const auto ours = ourHeaders(path);
        if (s.name.rfind("stream_", 0) == 0) {  // no grid offsets: OpenVDB read them whole at the open
            EXPECT_FALSE(ours) << s.name;
            continue;
        }
        ASSERT_TRUE(ours) << s.name;
        expectSameHeaders(*ours, *openvdbHeaders(path), s.name);
    }
    // Names that repeat and sort before the file's order, an instance (a grid sharing another's tree),
    // metadata of many types, a grid without a delayed-load table (no leaves), a scaled and rotated
    // transform.
    auto a = vdb_samples::fog();
    a->setName("zeta");
    a->insertMeta("label", openvdb::StringMetadata("smoke.density"));
    a->insertMeta("frame", openvdb::Int32Metadata(12));
    a->insertMeta("scale", openvdb::Vec3DMetadata(openvdb::Vec3d(1, 2, 3)));
    a->insertMeta("xform", openvdb::Mat4DMetadata(openvdb::Mat4d::identity()));
    auto b = a->copyGrid();  // shares the tree: written as an instance
    b->setName("alpha");
    auto c = vdb_samples::sphere();
    c->setName("zeta");
    openvdb::math::Transform::Ptr t = openvdb::math::Transform::createLinearTransform(0.25);
    t->preRotate(0.3, openvdb::math::Y_AXIS);
    c->setTransform(t);
    auto e = openvdb::DoubleGrid::create(1.0);
    e->setName("");
    const std::string path = d + "/mixed.vdb";
    vdb_samples::write(path, {a, b, c, e}, openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
    const auto ours = ourHeaders(path);
    ASSERT_TRUE(ours);
    expectSameHeaders(*ours, *openvdbHeaders(path), "mixed");
    // A transform other than a linear map is left to OpenVDB.
    auto f = vdb_samples::fog();
    f->setTransform(openvdb::math::Transform::createFrustumTransform(
        openvdb::BBoxd(openvdb::Vec3d(0), openvdb::Vec3d(15)), 0.5, 2.0, 1.0));
    vdb_samples::write(d + "/frustum.vdb", {f}, openvdb::io::COMPRESS_BLOSC);
    EXPECT_FALSE(ourHeaders(d + "/frustum.vdb"));
}

// Writes the samples as the fuzz corpus (tests/fuzz/corpus/vdb_read) when VDB_ISOSIMP_CORPUS_DIR is set.
TEST(DamagedVdb, WriteCorpus)
{
    const char* dir = std::getenv("VDB_ISOSIMP_CORPUS_DIR");
    if (!dir) GTEST_SKIP() << "set VDB_ISOSIMP_CORPUS_DIR to write the fuzz corpus";
    for (const auto& s : vdb_samples::samples()) s.write(std::string(dir) + "/" + s.name + ".vdb");
}

} // namespace

// LOD chains (--lods R1,R2,...) end to end: one run writes STEM_lod0.EXT ... ; each level is closed,
// manifold and within 2% of its face target; its finest level is as good as a run at that rate alone
// (RMS from the full surface within 2%, by mesh_error); bad chains are usage errors. The chain's time
// against one run at its coarsest rate is a benchmark (benchmarks/lods.sh), not a test: it needs an
// idle machine and alternating runs.
#include "tool_runs.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace {

using namespace vdb_isosimp::testing;

double rmsFromFull(const std::string& dir, const std::string& mesh)
{
    const ToolRun e = runTool(dir, q(MESH_ERROR_EXE) + " --json full.ply " + mesh);
    EXPECT_EQ(e.code, 0) << e.err;
    return jsonNumber(e.out, "rms", "a_to_b");
}

// A PLY file after its header (a chain's level names itself in a header comment).
std::string meshBody(const std::string& dir, const std::string& name)
{
    const std::string bytes = slurp(dir + "/" + name);
    return bytes.substr(bytes.find("end_header\n"));
}

TEST(Lods, OneRunWritesEveryLevel)
{
    const ScratchDir scratch;
    const std::string dir = scratch.path;
    ASSERT_EQ(runTool(dir, q(MAKE_VOLUME_EXE) + " noise -n 192 -o noise.vdb").code, 0);
    const std::string exe = q(VDB_ISOSIMP_EXE) + " noise.vdb -q ";
    const ToolRun lods = runTool(dir, exe + "--lods 0.2,0.05,0.01 -o chain.ply --report chain.json");
    ASSERT_EQ(lods.code, 0) << lods.err;
    EXPECT_FALSE(exists(dir + "/chain.ply")) << "a chain writes its levels only";

    const std::string report = slurp(dir + "/chain.json");
    // Large nodes near the top of the tree retire their interiors in every level, as in a run at one rate.
    EXPECT_GT(jsonNumber(report, "faces_retired"), 0) << "no level retired a face";
    for (int level = 0; level < 3; ++level) {
        const std::string name = "chain_lod" + std::to_string(level) + ".ply", p = "lod" + std::to_string(level) + "_";
        const ToolRun stats = runTool(dir, q(MESH_STATS_EXE) + " --json " + name);
        ASSERT_EQ(stats.code, 0) << name << ": " << stats.err;
        EXPECT_NE(stats.out.find("\"closed\": true"), std::string::npos) << name;
        EXPECT_NE(stats.out.find("\"manifold\": true"), std::string::npos) << name;
        const double faces = jsonNumber(stats.out, "faces"), target = jsonNumber(report, p + "faces_target");
        std::printf("level %d: %.0f faces, target %.0f (%+.2f%%)\n", level, faces, target, 100 * (faces / target - 1));
        EXPECT_EQ(faces, jsonNumber(report, p + "faces_out"));
        EXPECT_NEAR(faces, target, 0.02 * target) << name;
    }

    // The finest level is the mesh of a run at its rate alone, interiors retired near the top of the
    // tree as that run retires them (the header names the level); each coarser level is as close to the
    // full surface as a run at its rate alone.
    ASSERT_EQ(runTool(dir, exe + "-r 1 -o full.ply").code, 0);
    const char* rates[] = {"0.2", "0.05", "0.01"};
    for (int level = 0; level < 3; ++level) {
        const std::string chain = "chain_lod" + std::to_string(level) + ".ply", alone = std::string("alone") + rates[level] + ".ply";
        ASSERT_EQ(runTool(dir, exe + "-r " + rates[level] + " -o " + alone).code, 0);
        const double chainRms = rmsFromFull(dir, chain), aloneRms = rmsFromFull(dir, alone);
        std::printf("RMS from the full surface: level %d %.6g, -r %s alone %.6g\n", level, chainRms, rates[level], aloneRms);
        if (level == 0) EXPECT_TRUE(meshBody(dir, chain) == meshBody(dir, alone)) << "level 0 differs from a run at its rate";
        else EXPECT_LE(chainRms, 1.05 * aloneRms) << chain;
    }

    // The same levels from one thread: the chain does not depend on the threads.
    ASSERT_EQ(runTool(dir, exe + "-j 1 --lods 0.2,0.05,0.01 -o one.ply").code, 0);
    for (int level = 0; level < 3; ++level)
        EXPECT_TRUE(slurp(dir + "/one_lod" + std::to_string(level) + ".ply") ==
                    slurp(dir + "/chain_lod" + std::to_string(level) + ".ply")) << "level " << level;
}

TEST(Lods, HardContentLevelsAreExactAndClosed)
{
    // Flat faces and sharp edges (csg), voxels exactly at the iso-value (ct-int), small slabs so that
    // every level's copies and joins are many, and small nodes retiring their interiors: each level
    // closed, manifold, without zero-area faces, at its target, and as close to the full surface as a
    // run at its rate alone; the finest level is that run's mesh.
    const ScratchDir scratch;
    const std::string dir = scratch.path;
    for (const std::string kind : {"csg", "ct-int"}) {
        ASSERT_EQ(runTool(dir, q(MAKE_VOLUME_EXE) + " " + kind + " -n 96 -o v.vdb").code, 0) << kind;
        const std::string exe = q(VDB_ISOSIMP_EXE) + " v.vdb -q --slab-blocks 64 --retire-above 2000 ";
        ASSERT_EQ(runTool(dir, exe + "-r 1 -o full.ply").code, 0) << kind;
        const ToolRun lods = runTool(dir, exe + "--lods 0.2,0.05,0.01 -o chain.ply --report chain.json");
        ASSERT_EQ(lods.code, 0) << kind << ": " << lods.err;
        const std::string report = slurp(dir + "/chain.json");
        EXPECT_GT(jsonNumber(report, "faces_retired"), 0) << kind << ": no level retired a face";
        const char* rates[] = {"0.2", "0.05", "0.01"};
        for (int level = 0; level < 3; ++level) {
            const std::string name = "chain_lod" + std::to_string(level) + ".ply", p = "lod" + std::to_string(level) + "_";
            const ToolRun stats = runTool(dir, q(MESH_STATS_EXE) + " --json " + name);
            ASSERT_EQ(stats.code, 0) << kind << " " << name << ": " << stats.err;
            EXPECT_NE(stats.out.find("\"closed\": true"), std::string::npos) << kind << " " << name;
            EXPECT_NE(stats.out.find("\"manifold\": true"), std::string::npos) << kind << " " << name;
            EXPECT_EQ(jsonNumber(stats.out, "zero_area_faces"), 0) << kind << " " << name;
            const double faces = jsonNumber(stats.out, "faces"), target = jsonNumber(report, p + "faces_target");
            EXPECT_NEAR(faces, target, 0.02 * target) << kind << " " << name;
            ASSERT_EQ(runTool(dir, exe + "-r " + rates[level] + " -o alone.ply").code, 0) << kind;
            const double chainRms = rmsFromFull(dir, name), aloneRms = rmsFromFull(dir, "alone.ply");
            std::printf("%s level %d: %.0f faces (target %.0f), RMS %.6g, -r %s alone %.6g\n", kind.c_str(), level, faces,
                        target, chainRms, rates[level], aloneRms);
            EXPECT_LE(chainRms, 1.05 * aloneRms + 1e-9) << kind << " " << name;
            if (level == 0) {
                EXPECT_TRUE(meshBody(dir, name) == meshBody(dir, "alone.ply")) << kind << ": level 0 differs from -r 0.2";
            }
        }
    }
}

TEST(Lods, BadChainsAreUsageErrors)
{
    const ScratchDir scratch;
    const std::string dir = scratch.path;
    ASSERT_EQ(runTool(dir, q(MAKE_VOLUME_EXE) + " sphere -n 32 -o s.vdb").code, 0);
    for (const char* bad : {"--lods 0.2,0.3", "--lods 0.2,0.2", "--lods 0,0.1", "--lods 1.5,0.1", "--lods 0.2,-0.1",
                            "--lods 0.2,x", "--lods 0.2,0.1 -f 1000", "--lods 0.2,0.1 -r 0.5"}) {
        const ToolRun r = runTool(dir, q(VDB_ISOSIMP_EXE) + " s.vdb " + bad + " -o out.ply");
        EXPECT_EQ(r.code, 2) << bad << ": " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << bad << ": " << r.err;
        EXPECT_EQ(unexpectedFiles(dir, {"s.vdb"}), "") << bad;
    }
}

} // namespace

// Frame patterns (frame_sequence.h): which paths name a sequence, the path of each frame, and the
// frames a folder listing finds.
#include "vdb_isosimp/errors.h"
#include "vdb_isosimp/frame_sequence.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <unistd.h>

using namespace vdb_isosimp;

TEST(FramePattern, HashesAndPrintfNameTheSameFiles)
{
    const auto hashes = parseFramePattern("cache/smoke.####.vdb");
    const auto printf = parseFramePattern("cache/smoke.%04d.vdb");
    ASSERT_TRUE(hashes && printf);
    for (int f : {0, 7, 1234, 98765}) EXPECT_EQ(hashes->path(f), printf->path(f)) << f;
    EXPECT_EQ(hashes->path(7), "cache/smoke.0007.vdb");
    EXPECT_EQ(hashes->path(98765), "cache/smoke.98765.vdb");
    EXPECT_EQ(parseFramePattern("f.#.vdb")->path(12), "f.12.vdb");
    EXPECT_EQ(parseFramePattern("f.%d.vdb")->path(3), "f.3.vdb");
    EXPECT_EQ(parseFramePattern("f.%3d.vdb")->path(3), "f.  3.vdb");
    // The last pattern of the file name; none in a folder name or a plain name.
    EXPECT_EQ(parseFramePattern("v##/a.##.vdb")->path(5), "v##/a.05.vdb");
    EXPECT_FALSE(parseFramePattern("take#2/smoke.vdb"));
    EXPECT_FALSE(parseFramePattern("smoke.0001.vdb"));
    EXPECT_FALSE(parseFramePattern("100%.vdb"));
    EXPECT_FALSE(parseFramePattern("a.%%d.vdb"));
    EXPECT_FALSE(parseFramePattern("a.%s.vdb"));
}

TEST(FramePattern, FrameOfAcceptsOnlyWhatPathWrites)
{
    const auto p = parseFramePattern("d/f.####.vdb");
    ASSERT_TRUE(p);
    EXPECT_EQ(p->frameOf("d/f.0012.vdb"), 12);
    EXPECT_EQ(p->frameOf("d/f.12345.vdb"), 12345);
    EXPECT_FALSE(p->frameOf("d/f.012.vdb"));
    EXPECT_FALSE(p->frameOf("d/f.00012.vdb"));
    EXPECT_FALSE(p->frameOf("d/f.00a2.vdb"));
    EXPECT_FALSE(p->frameOf("d/f.0012.vdb.tmp"));
    EXPECT_FALSE(p->frameOf("e/f.0012.vdb"));
}

TEST(FramePattern, ListingAndRanges)
{
    const auto dir = std::filesystem::temp_directory_path() / ("frame_sequence_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    for (const char* name : {"f.0003.vdb", "f.0001.vdb", "f.0010.vdb", "f.010.vdb", "f.0002.vdb.tmp", "g.0004.vdb"})
        std::ofstream(dir / name) << "x";
    const auto p = parseFramePattern((dir / "f.####.vdb").string());
    ASSERT_TRUE(p);
    std::vector<int> numbers;
    for (const Frame& f : framePaths(*p)) {
        numbers.push_back(f.number);
        EXPECT_EQ(f.path, p->path(f.number));
    }
    EXPECT_EQ(numbers, (std::vector<int>{1, 3, 10}));
    EXPECT_EQ(framePaths(*p, 2).size(), 2u);            // existing frames from 2 on
    EXPECT_EQ(framePaths(*p, std::nullopt, 3).size(), 2u);
    EXPECT_EQ(framePaths(*p, 2, 5).size(), 4u);         // a range: every frame, existing or not
    EXPECT_THROW(framePaths(*p, 5, 2), InputError);
    EXPECT_THROW(framePaths(*p, 0, 5000000), InputError);
    EXPECT_THROW(framePaths(*parseFramePattern((dir / "none/f.####.vdb").string())), InputError);
    std::filesystem::remove_all(dir);
    // A pattern without a folder lists the current one.
    EXPECT_NO_THROW(framePaths(*parseFramePattern("no_such_file_here.####.vdb")));
}

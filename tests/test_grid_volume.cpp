// Volume::fromGrid (an in-memory grid, read only) gives what Volume::open gives for the same grid read
// from a file: the same info, block list, samples and value range; and it never frees the caller's voxels.
#include "fuzz/vdb_samples.h"
#include "test_grids.h"
#include "vdb/block_order.h"
#include "vdb/volume_reader.h"

#include "vdb_isosimp/vdb_isosimp.h"

#include "vdb_isosimp/errors.h"

#include <gtest/gtest.h>

#include <openvdb/tools/LevelSetSphere.h>

#include <sys/mman.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <random>
#include <filesystem>
#include <set>

namespace vi = vdb_isosimp;
namespace vt = vdb_isosimp::testing;

namespace {

// The most leaves in one z-layer of leaves, counted leaf by leaf (the memory estimate's layer size).
uint64_t fullestLeafLayer(const openvdb::GridBase& grid)
{
    std::map<int32_t, uint64_t> perLayer;
    const auto count = [&](const auto& tree) {
        for (auto it = tree.cbeginLeaf(); it; ++it) ++perLayer[it->origin().z()];
    };
    if (const auto* f = dynamic_cast<const openvdb::FloatGrid*>(&grid)) count(f->tree());
    if (const auto* d = dynamic_cast<const openvdb::DoubleGrid*>(&grid)) count(d->tree());
    uint64_t most = 0;
    for (const auto& layer : perLayer) most = std::max(most, layer.second);
    return most;
}

// A file's volume, its leaves kept and read from the file, samples every block as the grid read whole does.
void expectSameSamples(vi::Volume& fromFile, const vi::Volume& inMemory, const std::vector<vi::BlockOrigin>& blocks)
{
    fromFile.keepLeaves({});
    vi::BlockSamples s1, s2;
    for (const auto& o : blocks) {
        fromFile.sample(o, s1);
        inMemory.sample(o, s2);
        ASSERT_EQ(s1.values, s2.values);
    }
}

void expectSameVolume(openvdb::FloatGrid::Ptr grid, const std::string& name)
{
    grid->setName(name);
    const auto fromFile = vi::Volume::open(vt::writeGrid(grid, "gridvolume_" + name), "");
    const auto inMemory = vi::Volume::fromGrid(grid, "in-memory grid '" + name + "'");
    const vi::VolumeInfo &a = fromFile->info(), &b = inMemory->info();
    EXPECT_EQ(a.gridName, b.gridName);
    EXPECT_EQ(a.valueType, b.valueType);
    EXPECT_EQ(a.levelSet, b.levelSet);
    EXPECT_EQ(a.indexToWorld.m, b.indexToWorld.m);
    EXPECT_EQ(a.background, b.background);
    EXPECT_EQ(a.leafCount, b.leafCount);
    EXPECT_EQ(a.activeVoxels, b.activeVoxels);
    EXPECT_EQ(a.maxLeavesPerLayer, fullestLeafLayer(*grid));
    EXPECT_EQ(b.maxLeavesPerLayer, fullestLeafLayer(*grid));
    EXPECT_EQ(fromFile->valueRange(), inMemory->valueRange());

    vi::Classifier c;
    c.insideBelow = a.levelSet;
    c.iso = a.levelSet ? 0.0 : 0.5;
    const auto blocks = fromFile->blocks(c);
    ASSERT_EQ(blocks, inMemory->blocks(c));
    ASSERT_FALSE(blocks.empty());
    vi::BlockSamples s1, s2;
    for (const auto& o : blocks) {
        fromFile->sample(o, s1);
        inMemory->sample(o, s2);
        ASSERT_EQ(s1.values, s2.values);
        inMemory->releaseLeaf(o);
    }
    for (auto leaf = grid->tree().cbeginLeaf(); leaf; ++leaf) ASSERT_FALSE(leaf->buffer().empty());
}

// A random sparse grid written to a file and opened from it (delayed loading).
struct FileVolume {
    openvdb::FloatGrid::Ptr grid;
    std::string path;
    std::unique_ptr<vi::Volume> volume;
};

FileVolume fileVolume(unsigned seed, const std::string& name)
{
    openvdb::initialize();
    vt::GridSpec spec;
    spec.seed = seed;
    FileVolume f;
    f.grid = vt::randomSparseGrid(spec);
    f.grid->setName(name);
    f.path = vt::writeGrid(f.grid, "file_volume_" + name);
    f.volume = vi::Volume::open(f.path, "");
    return f;
}

// The blocks of a volume whose surface is at 0 (the random grids' level).
std::vector<vi::BlockOrigin> blocksAtZero(const vi::Volume& vol)
{
    vi::Classifier c;
    c.insideBelow = vol.info().levelSet;
    c.iso = 0.0;
    return vol.blocks(c);
}

} // namespace

TEST(GridVolume, SameAsTheFileReader)
{
    openvdb::initialize();
    for (unsigned seed : {1u, 2u, 3u}) {
        vt::GridSpec spec;
        spec.seed = seed;
        spec.levelSet = seed != 2;
        spec.mirrored = seed == 3;
        spec.bigTile = seed == 1;
        expectSameVolume(vt::randomSparseGrid(spec), "g" + std::to_string(seed));
    }
}

TEST(GridVolume, RejectsWhatTheFileReaderRejects)
{
    openvdb::initialize();
    auto vec = openvdb::Vec3SGrid::create();
    vec->setName("vel");
    try {
        vi::Volume::fromGrid(vec, "in-memory grid 'vel'");
        ADD_FAILURE();
    } catch (const vi::InputError& e) {
        EXPECT_STREQ(e.what(), "in-memory grid 'vel': grid 'vel' has value type vec3s; only float and double grids "
                               "can be meshed");
    }
    auto empty = openvdb::FloatGrid::create(1.0f);
    empty->setName("nothing");
    EXPECT_THROW(vi::Volume::fromGrid(empty, "x"), vi::InputError);
}

TEST(FileVolume, ReadsEveryStoredFormatAsOpenVDBLoadsIt)
{
    // OpenVDB reads the topology alone and the voxels come from each leaf's record, read with pread()
    // and decoded here (StoredLeaves): every block's samples equal those of the grid OpenVDB reads whole,
    // for every way it stores a scalar grid (blosc, zip, none, active-mask compression, half floats,
    // double, level sets with their negative inactive values, several grids in one file, files written
    // as a stream).
    openvdb::initialize();
    size_t grids = 0;
    for (const auto& sample : vdb_samples::samples()) {
        SCOPED_TRACE(sample.name);
        const std::string path = ::testing::TempDir() + "/stored_" + sample.name + ".vdb";
        sample.write(path);
        openvdb::io::File whole(path);
        whole.open(/*delayLoad=*/false);
        for (auto it = whole.beginName(); it != whole.endName(); ++it) {
            openvdb::GridBase::Ptr grid = whole.readGrid(it.gridName());
            if (!grid->isType<openvdb::FloatGrid>() && !grid->isType<openvdb::DoubleGrid>()) continue;
            if (grid->baseTree().leafCount() == 0) continue;
            SCOPED_TRACE(it.gridName());
            const auto fromFile = vi::Volume::open(path, grid->getName());
            const auto inMemory = vi::Volume::fromGrid(grid, "grid read whole");
            EXPECT_TRUE(fromFile->readsStoredRecords());
            EXPECT_EQ(fromFile->info().leafCount, grid->baseTree().leafCount());
            EXPECT_EQ(fromFile->info().maxLeavesPerLayer, fullestLeafLayer(*grid));
            // The value range a fog grid's default iso-value comes from: read leaf by leaf from the
            // records, against the grid read whole.
            EXPECT_EQ(fromFile->valueRange(), inMemory->valueRange());
            vi::Classifier c;
            c.insideBelow = fromFile->info().levelSet;
            c.iso = c.insideBelow ? 0.0 : 0.5;
            const auto blocks = fromFile->blocks(c);
            ASSERT_FALSE(blocks.empty());
            expectSameSamples(*fromFile, *inMemory, blocks);
            ++grids;
        }
    }
    EXPECT_GE(grids, 12u);
}

TEST(FileVolume, ReadsTheTopologyOfManyNodesAsOpenVDBDoes)
{
    // The lower internal nodes are read on all threads, the root and upper nodes in order: a tree with
    // tiles at every level (a root tile, an upper node of tiles only, lower tiles inside and outside),
    // leaves in 150 lower nodes across eight upper nodes on both sides of the origin, read as OpenVDB
    // reads it whole, for each way a file stores it.
    openvdb::initialize();
    auto grid = openvdb::FloatGrid::create(3.0f);
    grid->setName("surface");
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    auto& tree = grid->tree();
    tree.addTile(3, openvdb::Coord(8192, 0, 0), 5.0f, true);  // a root tile, outside (the largest value)
    tree.addTile(2, openvdb::Coord(-8192, 4096, 0), -3.0f, false);  // an upper node's tile, no leaf below it
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> val(-2.0f, 2.0f);
    for (int i = 0; i < 150; ++i) {
        const openvdb::Coord o(128 * (i % 5 - 2), 128 * (i / 5 % 6 - 3) + 8 * (i % 3), 128 * (i / 30 - 2) + 16);
        auto* leaf = tree.touchLeaf(o);
        for (openvdb::Index n = 0; n < openvdb::FloatTree::LeafNodeType::SIZE; n += 1 + n % 3) leaf->setValueOn(n, val(rng));
        tree.addTile(1, o.offsetBy(32, 0, 0), i % 2 ? -1.5f : 1.5f, i % 4 == 0);
    }
    using namespace openvdb::io;
    for (const uint32_t compression : {uint32_t(COMPRESS_NONE), uint32_t(COMPRESS_ZIP), uint32_t(COMPRESS_BLOSC | COMPRESS_ACTIVE_MASK)})
        for (const bool half : {false, true}) {
            SCOPED_TRACE("compression " + std::to_string(compression) + (half ? ", half floats" : ""));
            grid->setSaveFloatAsHalf(half);
            const std::string path = ::testing::TempDir() + "/many_nodes.vdb";
            vdb_samples::write(path, {grid}, compression);
            File whole(path);
            whole.open(/*delayLoad=*/false);
            const auto read = whole.readGrid("surface");
            const auto fromFile = vi::Volume::open(path, "");
            const auto inMemory = vi::Volume::fromGrid(read, "grid read whole");
            EXPECT_TRUE(fromFile->readsStoredRecords());
            const vi::VolumeInfo &a = fromFile->info(), &b = inMemory->info();
            EXPECT_EQ(a.leafCount, 150u);
            EXPECT_EQ(a.leafCount, b.leafCount);
            EXPECT_EQ(a.activeVoxels, b.activeVoxels);
            EXPECT_EQ(a.maxLeavesPerLayer, fullestLeafLayer(*read));
            EXPECT_EQ(fromFile->valueRange(), inMemory->valueRange());
            vi::Classifier c;
            c.insideBelow = true;
            EXPECT_EQ(fromFile->tileShellBlocks(c), inMemory->tileShellBlocks(c));
            const auto blocks = fromFile->blocks(c);
            ASSERT_EQ(blocks, inMemory->blocks(c));
            expectSameSamples(*fromFile, *inMemory, blocks);
        }
}

TEST(FileVolume, DroppingTheInputMappingNeverTouchesOtherMemory)
{
    // trimInputMapping() drops the pages of the input file's mapping. The mapping is unmapped once no
    // voxel buffer is left on disk, and its addresses may then come back as heap memory: the volume
    // must keep it alive, or dropping "its" pages would zero live data.
    const FileVolume f = fileVolume(5, "trim");
    const std::string& path = f.path;
    const auto& vol = f.volume;
    vol->trimInputMapping();  // looks the mapping up while buffers are still on disk
    vi::Classifier c;
    c.insideBelow = vol->info().levelSet;
    c.iso = c.insideBelow ? 0.0 : 0.5;
    vi::BlockSamples s;
    const auto blocks = vol->blocks(c);
    ASSERT_FALSE(blocks.empty());
    for (const auto& o : blocks) {
        vol->sample(o, s);
        vol->releaseLeaf(o);
    }
    // Fresh memory of the file's size: where the mapping was, if it had gone.
    const size_t bytes = std::filesystem::file_size(path) + 4096;
    void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    ASSERT_NE(p, MAP_FAILED);
    std::memset(p, 0xAB, bytes);
    vol->trimInputMapping();
    const unsigned char* b = static_cast<const unsigned char*>(p);
    size_t changed = 0;
    for (size_t i = 0; i < bytes; ++i) changed += b[i] != 0xAB;
    ::munmap(p, bytes);
    EXPECT_EQ(changed, 0u);
}

TEST(FileVolume, AParkedLeafReadsTheSameVoxelsAgain)
{
    // A leaf loaded by a reloadable read and parked goes back to disk: the next read decodes it from
    // the file again and must see the same voxels. A leaf loaded without the mark is never parked,
    // and a parked leaf read again without it stays.
    const FileVolume f = fileVolume(7, "park");
    const auto& grid = f.grid;
    const auto& vol = f.volume;
    vi::Classifier c;
    c.insideBelow = vol->info().levelSet;
    c.iso = 0.0;
    const auto blocks = vol->blocks(c);
    const auto leavesOf = [](const std::array<int32_t, 3>& o) {
        std::vector<std::array<int32_t, 3>> l;
        for (int d = 0; d < 8; ++d) l.push_back(vi::sampledLeaf(o, d));
        return l;
    };
    const auto storedLeaves = [&](const std::array<int32_t, 3>& o) {
        uint64_t n = 0;
        for (const auto& l : leavesOf(o)) n += grid->tree().probeConstLeaf(openvdb::Coord(l[0], l[1], l[2])) != nullptr;
        return n;
    };
    // A block whose cells read leaves (not only tiles).
    const auto withLeaves = std::find_if(blocks.begin(), blocks.end(), [&](const std::array<int32_t, 3>& o) { return storedLeaves(o) > 0; });
    ASSERT_NE(withLeaves, blocks.end());
    const auto a = *withLeaves;
    const auto apart = std::find_if(blocks.begin(), blocks.end(), [&](const std::array<int32_t, 3>& o) {
        for (const auto& x : leavesOf(a))
            for (const auto& y : leavesOf(o))
                if (x == y) return false;
        return true;
    });
    ASSERT_NE(apart, blocks.end());
    vi::BlockSamples first, other, reread;
    vol->sample(*apart, other, 0);
    for (const auto& l : leavesOf(*apart)) vol->parkLeaf(l);
    EXPECT_EQ(vol->parkedLeaves(), 0u);

    const uint64_t stored = storedLeaves(a);
    vol->sample(a, first, 0xff);
    for (const auto& l : leavesOf(a)) vol->parkLeaf(l);
    EXPECT_EQ(vol->parkedLeaves(), stored);
    vol->sample(a, reread, 0);
    EXPECT_EQ(reread.values, first.values);
    for (const auto& l : leavesOf(a)) vol->parkLeaf(l);
    EXPECT_EQ(vol->parkedLeaves(), stored);
}

TEST(FileVolume, ACopyReaderReadsTheVoxelsAndLeavesTheVolumeOnDisk)
{
    // A face target's count reads every block through a copy reader, then extraction runs on the same
    // volume: the reader must give the grid's voxels and leave the volume's own leaves unread. A read
    // that loads a leaf with the reloadable mark lets parkLeaf park it; a leaf already in memory
    // (loaded by the count) is never parked.
    const FileVolume f = fileVolume(11, "copies");
    const auto& vol = f.volume;
    const auto inMemory = vi::Volume::fromGrid(f.grid, "in-memory grid");
    const auto blocks = blocksAtZero(*vol);
    ASSERT_FALSE(blocks.empty());
    std::set<std::array<int32_t, 3>> stored;
    for (const auto& o : blocks)
        for (int d = 0; d < 8; ++d) {
            const auto l = vi::sampledLeaf(o, d);
            if (f.grid->tree().probeConstLeaf(openvdb::Coord(l[0], l[1], l[2]))) stored.insert(l);
        }
    ASSERT_GT(stored.size(), 10u);
    vi::BlockSamples a, b;
    for (int pass = 0; pass < 2; ++pass) {
        // Twice: the second reader after the first one's copies are gone (their pool slots reused
        // within a reader, released in block order as the count releases them).
        const auto copies = vol->copyReader();
        for (const auto& o : blocks) {
            copies->sample(o, a);
            inMemory->sample(o, b);
            ASSERT_EQ(a.values, b.values);
            if (pass == 0) copies->release(o);
        }
    }
    for (const auto& o : blocks) {
        vol->sample(o, a, 0xff);
        inMemory->sample(o, b);
        ASSERT_EQ(a.values, b.values);
    }
    for (const auto& l : stored) vol->parkLeaf(l);
    EXPECT_EQ(vol->parkedLeaves(), stored.size());
}

TEST(FileVolume, ARankKeepsTheLeavesItsBlocksSampleAndNoOther)
{
    // An MPI rank extracts a run of the block list: it keeps the leaves those blocks sample (their
    // own and the plane above them) and deletes the rest of the topology. Its blocks read the grid's
    // voxels as before; blocks whose leaves all lie elsewhere read background tiles in their place
    // (some of them differ from the grid then). The whole list keeps every leaf.
    for (const bool whole : {false, true}) {
        const FileVolume f = fileVolume(13, whole ? "all_leaves" : "rank_leaves");
        const auto& vol = f.volume;
        const auto inMemory = vi::Volume::fromGrid(f.grid, "in-memory grid");
        const auto blocks = blocksAtZero(*vol);
        ASSERT_GT(blocks.size(), 30u);
        const size_t begin = whole ? 0 : blocks.size() / 3, end = whole ? blocks.size() : 2 * blocks.size() / 3;
        std::set<std::array<int32_t, 3>> kept;
        for (size_t i = begin; i < end; ++i)
            for (int d = 0; d < 8; ++d) kept.insert(vi::sampledLeaf(blocks[i], d));
        if (whole) vol->keepLeaves({});
        else vol->keepLeaves([&](const std::array<int32_t, 3>& leaf) { return kept.count(leaf) > 0; });
        vi::BlockSamples a, b;
        size_t elsewhere = 0;
        for (size_t i = 0; i < blocks.size(); ++i) {
            vol->sample(blocks[i], a);
            inMemory->sample(blocks[i], b);
            if (i >= begin && i < end) {
                ASSERT_EQ(a.values, b.values) << "block " << i;
                continue;
            }
            bool stored = false, keptAny = false;
            for (int d = 0; d < 8; ++d) {
                const auto l = vi::sampledLeaf(blocks[i], d);
                keptAny |= kept.count(l) > 0;
                stored |= f.grid->tree().probeConstLeaf(openvdb::Coord(l[0], l[1], l[2])) != nullptr;
            }
            if (whole) ASSERT_EQ(a.values, b.values) << "block " << i;
            else if (stored && !keptAny && a.values != b.values) ++elsewhere;
        }
        if (!whole) {
            EXPECT_GT(elsewhere, 0u);
        }
    }
}

TEST(FileVolume, ParkingLeavesBetweenBandsKeepsTheMesh)
{
    // With small slabs a sphere spans many bands, and a leaf on a band's edge is read by the band
    // below it long before its own: the file run parks those leaves and reads them again, the
    // in-memory run (whose leaves are never freed) does not. Same mesh either way, with 1 and 2 threads.
    openvdb::initialize();
    auto grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(28.0f, openvdb::Vec3f(0.5f, -0.3f, 0.2f), 1.0f, 3.0f);
    grid->setName("ball");
    const std::string path = vt::writeGrid(grid, "park_bands");
    for (int threads : {1, 2}) {
        vi::Options o;
        o.ratio = 0.1;
        o.blocksPerSlab = 24;
        o.threads = threads;
        const vi::Result file = vi::simplifyFile(path, o);
        const vi::Result memory = vi::simplifyGrid(*grid, o);
        ASSERT_GT(file.report.slabs, 20u);
        EXPECT_EQ(file.mesh.points, memory.mesh.points);
        EXPECT_EQ(file.mesh.triangles, memory.mesh.triangles);
    }
}

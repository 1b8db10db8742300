// Volume reader: opens a scalar grid of an OpenVDB file without its voxels (OpenVDB reads the topology;
// each leaf's voxels are read from its stored record when first sampled, or through OpenVDB's delayed
// loading where the records were not walked) and gives the rest of the pipeline what it needs,
// independent of float/double: the block list, 9^3 block samples, the index-to-world map and the
// grid's sign convention.
#pragma once
#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "core/marching_cubes.h"

#include <openvdb/openvdb.h>

namespace vdb_isosimp {

// The stored records of a grid's leaves that this process has not walked yet (input_checks.h).
struct LeafRecords;
// Where the leaves' records lie in the file, by origin, for reading their voxels (volume_reader.cpp).
class StoredLeaves;

// The processes of a distributed run share the walk of the leaf records (input_checks.h: LeafWalkShare):
// each walks part `part` of `parts` of them, then `agree` is called exactly once per open with
// whether this process walked its part (false: it stopped before, a missing file or a damaged
// header, and has no say), whether the part was sound, and the digest of its stored tree
// (VdbGridLayout::digest). It returns true when every process walked a sound part; false makes each
// walk every record as one process does, which names a fault the same way everywhere. It throws on
// every process when all walked and the digests differ: copies that differ would make a mesh of
// neither file. A process walks the records of the leaves it keeps (keepLeaves) before it reads them.
struct TreeAgreement {
    size_t part = 0, parts = 1;
    std::function<bool(bool walked, bool sound, uint64_t digest)> agree;
};

struct VolumeInfo {
    std::string file;
    std::string gridName;
    std::string valueType;      // "float" or "double"
    bool levelSet = false;      // grid class level set: inside is value < iso
    Affine indexToWorld;
    double background = 0.0;
    uint64_t leafCount = 0;
    uint64_t activeVoxels = 0;
    // For the memory estimate (input_checks.h), from the topology alone. Where a distributed run's
    // process read its share of the topology (open with a TreeAgreement of several parts), leafCount
    // counts the file's leaves and activeVoxels and these two the share's.
    uint64_t topologyBytes = 0;      // tree nodes without the voxel buffers
    uint64_t maxLeavesPerLayer = 0;  // leaves in the fullest z-layer of leaves
    uint64_t valueBytes = 4;         // sizeof(float) or sizeof(double)
    // Of opening a file: the walk of its stored tree before OpenVDB reads it (checkVdbGridData),
    // whose leaf records divide among threads.
    double checkSeconds = 0.0;
    // And OpenVDB's read of the topology, whose lower nodes divide among threads (0: read by OpenVDB alone).
    double topologySeconds = 0.0;
};

class Volume {
public:
    // Opens `gridName` of `path` (empty: the first level set, else the grid named density, else the
    // first float/double grid; Options::gridName): the file's structure, the
    // grid's type, class, transform and index bounding box are checked before any voxel is read
    // (input_checks.h); OpenVDB's own exceptions become InputError too.
    // With an agreement (a distributed run's processes), it is called exactly once, whatever happens,
    // or the other processes would wait for this one.
    // @throw InputError naming the file and the problem.
    static std::unique_ptr<Volume> open(const std::string& path, const std::string& gridName,
                                        const TreeAgreement& agreement = {});
    // A read-only view of a grid already in memory (the library's grid-in entry point): its voxel
    // buffers are never released. `label` names it in messages. @throw InputError as open() does.
    static std::unique_ptr<Volume> fromGrid(openvdb::GridBase::ConstPtr grid, const std::string& label);
    virtual ~Volume() = default;

    const VolumeInfo& info() const { return mInfo; }

    // Origins of every block that may hold a straddling cell, sorted by z, then y, then x (block_order.cpp);
    // part `part` of `parts`: those of that share of the leaves and tiles, whose lists merged are the
    // whole list (a distributed run's ranks divide it).
    virtual std::vector<std::array<int32_t, 3>> blocks(const Classifier& c, size_t part = 0, size_t parts = 1) const = 0;
    // Keeps the leaves `keep` accepts (by origin; empty: all of them), laid out in sweep order so that
    // their pages empty as extraction releases them, and deletes every other leaf (an MPI rank keeps
    // the leaves its own slabs sample, not the whole topology). Once, after blocks() and before any
    // sample. A caller's grid is left as it is. Where the open shared the walk of the leaf records
    // among processes, the kept leaves' records this process did not walk are walked first.
    // @throw InputError for a damaged record among them.
    virtual void keepLeaves(const std::function<bool(const std::array<int32_t, 3>& leafOrigin)>& keep) = 0;
    // Reads the topology this process left on disk wherever the samples of these blocks reach: a
    // distributed run's rank reads its share of the lower nodes as it opens the file and the others its
    // slabs sample once it knows them (before keepLeaves). Nothing to do for a whole tree.
    // @throw InputError where the file no longer holds what the open found.
    virtual void readAround(const std::array<int32_t, 3>* blocks, size_t count) { (void)blocks, (void)count; }
    // How many of those the tiles' faces add (countTileShellBlocks), without listing them.
    virtual uint64_t tileShellBlocks(const Classifier& c) const = 0;
    // Fills the 9^3 samples of the block at `origin`. Thread-safe. @throw InputError on NaN/Inf or
    // when the voxels cannot be read from the file (delayed loading). Bit d of `reloadable` stands for
    // the leaf at origin + 8 * (d & 1, d >> 1 & 1, d >> 2 & 1): if this read is the one that loads it,
    // the leaf may be parked afterwards (parkLeaf).
    virtual void sample(const std::array<int32_t, 3>& origin, BlockSamples& out, uint8_t reloadable = 0) const = 0;
    // Frees the leaf whose origin is `blockOrigin`, if any. A leaf is sampled by its own block and the
    // up to 7 blocks below, behind and left of it (their +x/+y/+z corner layers): the caller frees it once
    // all of those it extracts have been integrated (pipeline.cpp counts them), so live voxel data stays
    // about one layer of blocks per slab in progress. Thread-safe; nothing may sample the leaf afterwards.
    virtual void releaseLeaf(const std::array<int32_t, 3>& blockOrigin) = 0;
    // Drops the voxels of a leaf that a sample() marked reloadable loaded, but keeps the leaf: the next
    // sample reads them from the file again. For a leaf whose other readers come much later (a leaf just
    // above a cut of the merge tree is read by the blocks below the cut, a whole subtree before its own:
    // slabs.h), so that a plane of leaves does not wait in memory in between. Thread-safe;
    // nothing may sample the leaf while this runs. A no-op for a leaf not loaded that way.
    virtual void parkLeaf(const std::array<int32_t, 3>& blockOrigin) = 0;
    // How many leaves parkLeaf has parked so far.
    uint64_t parkedLeaves() const { return mParked.load(std::memory_order_relaxed); }
    // True where the voxels are read from the leaves' records as the walk of the stored tree found them
    // (every checked file with grid offsets: OpenVDB then reads the topology alone), false where
    // OpenVDB's delayed load reads them.
    bool readsStoredRecords() const { return mStored != nullptr; }

    // A pass over the blocks before extraction (the face count of a face target) that leaves this
    // volume as opened: each leaf still on disk is read into a copy of its own, kept until release(),
    // so the volume's leaves stay unread in their sweep-order layout and extraction follows on the
    // same volume. A second open would read the topology again, on every MPI rank.
    class CopyReader {
    public:
        virtual ~CopyReader() = default;
        // As Volume::sample. Thread-safe. @throw InputError on NaN/Inf or unreadable voxels.
        virtual void sample(const std::array<int32_t, 3>& origin, BlockSamples& out) = 0;
        // Frees the copy of the leaf whose origin is `blockOrigin`, if any (once every block that
        // samples it is done, as for releaseLeaf). Thread-safe.
        virtual void release(const std::array<int32_t, 3>& blockOrigin) = 0;
    };
    // Copies left unreleased go with the reader.
    virtual std::unique_ptr<CopyReader> copyReader() const = 0;
    // A reader whose copies are its own, all freed with it (release does nothing): for a few blocks
    // read apart from the others, such as one run of a sampled count, whose neighbours' leaves no
    // later block of the same reader would release. One thread at a time.
    virtual std::unique_ptr<CopyReader> privateCopyReader() const = 0;
    // Pages between calls are what some blocks' leaf reads faulted in; every 128 blocks keeps them to
    // a few MB. Each call walks the page tables of the whole mapping and flushes the other threads'
    // TLBs, so calling more often costs system time that grows with the file (docs/perf.md).
    static constexpr size_t kTrimEveryBlocks = 128;
    // Delayed loading maps the input file; the pages read so far stay counted in the process's
    // resident memory although the voxels they held were decoded long ago. Drops those pages from
    // this process (they stay in the page cache and fault back in if read again), so resident memory
    // follows the output rather than the input file. Safe while other threads read the file. Call it
    // often (every few blocks) where voxels are read through the mapping (!readsStoredRecords()): each
    // leaf read faults in the pages around it too (fault-around, 64 KB), and leaves lie in the file in
    // tree order, not in sweep order. Where they are read from their records, the open's call (after
    // the topology) is the only one needed.
    void trimInputMapping() const;
    // Smallest and largest value stored in the grid (voxels, tiles and background); of the voxels, only
    // those of part `part` of `parts` of the leaves (a distributed run's ranks each read their part).
    virtual std::array<double, 2> valueRange(size_t part = 0, size_t parts = 1) const = 0;

protected:
    VolumeInfo mInfo;
    // The records another process walked (TreeAgreement): keepLeaves walks those of the kept leaves.
    std::shared_ptr<const LeafRecords> mUnwalked;
    // Set where the walk of the stored tree found every leaf's record: a leaf's voxels are read from
    // the file with pread() and decoded here, not through OpenVDB's mapping of the file.
    std::shared_ptr<StoredLeaves> mStored;
    bool mFromFile = true;  // read from a file, voxels on disk until sampled: freed as blocks finish
    bool mHoldsMapping = false;  // keeps the input file's mapping alive, so trimInputMapping may cache it
    std::atomic<uint64_t> mParked{0};

private:
    mutable std::once_flag mMappedOnce;
    mutable std::vector<std::pair<unsigned long, size_t>> mMapped;  // the input file's mapped ranges
};

} // namespace vdb_isosimp

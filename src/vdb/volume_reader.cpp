#include "vdb/volume_reader.h"

#include "core/stopwatch.h"
#include "vdb/block_order.h"
#include "vdb/input_checks.h"
#include "vdb_isosimp/errors.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/Compression.h>
#include <openvdb/io/File.h>
#include <openvdb/io/io.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <sys/mman.h>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include <fcntl.h>
#include <malloc.h>
#include <unistd.h>

namespace vdb_isosimp {

// The leaves' records as the walk of the stored tree found them (input_checks.h), by origin. A leaf's
// voxels are read with one pread() of its record and decoded by OpenVDB's readCompressedValues, as its
// delayed load would (LeafBuffer::doLoad), without the mapping of the file that the delayed load reads
// through: there each leaf faults its pages and 64 KB around them into this process, which has to
// drop them again (trimInputMapping) and fault them back for the next leaf of the same pages, as
// leaves lie in the file in tree order, not in sweep order. A read copies from the page cache and
// maps nothing.
// A leaf's or a node's origin as a key that ascends in the order OpenVDB's 5-4-3 tree lists its leaves
// and nodes (the root's nodes by origin, x first; a node's children by offset, x slowest), so what is
// kept in the file's order needs no sort. Origins lie within the vertex keys' range (checked at the
// open): 8 bits per root coordinate, 5 per upper node, 4 per lower node.
inline uint64_t treeKey(int32_t x, int32_t y, int32_t z)
{
    const auto root = [](int32_t c) { return uint64_t((c >> 12) + 128) & 0xFF; };
    const auto part = [](int32_t c, int shift, uint32_t mask) { return uint64_t((uint32_t(c) >> shift) & mask); };
    return root(x) << 51 | root(y) << 43 | root(z) << 35 | part(x, 7, 31) << 30 | part(y, 7, 31) << 25 |
           part(z, 7, 31) << 20 | part(x, 3, 15) << 16 | part(y, 3, 15) << 12 | part(z, 3, 15) << 8;
}

class StoredLeaves {
public:
    // `origins` in file order (the tree's), one per record of `layout`. Unusable (usable() false) where
    // the records cannot be kept this way. Every leaf's record is held; or, given `starts` (the layout's
    // own record starts, moved in here), none until hold() names them: a distributed run's rank reads
    // a few of the file's leaves.
    StoredLeaves(const std::string& path, const VdbGridLayout& layout, const std::vector<std::array<int32_t, 3>>& origins,
                 std::vector<uint64_t>* starts = nullptr)
        : mFd(::open(path.c_str(), O_RDONLY | O_CLOEXEC)), mFileVersion(layout.fileVersion),
          mCompression(layout.compression), mHalf(layout.half)
    {
        const auto& at = layout.recordStarts;
        if (mFd < 0 || at.size() != origins.size() + 1 || mFileVersion < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION)
            return;
        for (size_t i = 0; i < origins.size(); ++i)
            if (at[i + 1] <= at[i] || at[i + 1] - at[i] > kSizeMask || at[i] >> (64 - kSizeBits)) return;
        mUsable = true;
        if (starts) {
            mAt = std::move(*starts);  // `at` is *starts: not read again
            mHolding = Holding::Some;
            return;
        }
        mRecords.reserve(origins.size());
        for (size_t i = 0; i < origins.size(); ++i) mRecords.push_back(record(origins[i], at[i], at[i + 1]));
        sortByKey();
    }

    // Holds the records of the leaves in `runs` ([first, end) of `origins`, those of the constructor) too.
    // After the `last` call the record starts go: no other leaf can be held, and a later call throws
    // std::logic_error rather than leave a leaf without its record.
    void hold(const std::vector<std::array<int32_t, 3>>& origins, const std::vector<std::array<size_t, 2>>& runs,
              bool last = false)
    {
        if (!mUsable || mHolding == Holding::All) return;
        if (mHolding == Holding::Done) throw std::logic_error("a leaf record held after the last hold()");
        for (const auto& run : runs)
            for (size_t i = run[0]; i < run[1]; ++i) mRecords.push_back(record(origins[i], mAt[i], mAt[i + 1]));
        sortByKey();
        if (last) {
            std::vector<uint64_t>().swap(mAt);
            mHolding = Holding::Done;
        }
    }
    ~StoredLeaves()
    {
        if (mFd >= 0) ::close(mFd);
    }
    StoredLeaves(const StoredLeaves&) = delete;
    StoredLeaves& operator=(const StoredLeaves&) = delete;

    bool usable() const { return mUsable; }

    // Reads the voxels of the leaf at `origin` into `values` (LeafT::SIZE of them); false where no
    // record has that origin. @throw std::runtime_error (or OpenVDB's exceptions) when the record
    // cannot be read or decoded.
    template <typename ValueT>
    bool read(const openvdb::Coord& origin, ValueT* values, const ValueT& background) const
    {
        const uint64_t key = treeKey(origin.x(), origin.y(), origin.z());
        const auto it = std::lower_bound(mRecords.begin(), mRecords.end(), key,
                                         [](const Record& r, uint64_t k) { return r.key < k; });
        if (it == mRecords.end() || it->key != key) return false;
        const uint64_t start = it->at >> kSizeBits;
        const size_t size = size_t(it->at & kSizeMask);
        thread_local RecordStream in;
        in.bytes.resize(size);
        for (size_t done = 0; done < size;) {
            const ssize_t n = ::pread(mFd, in.bytes.data() + done, size - done, off_t(start + done));
            if (n <= 0) throw std::runtime_error("its record cannot be read");
            done += size_t(n);
        }
        in.buffer.over(in.bytes.data(), size);
        in.stream.clear();
        openvdb::io::setVersion(in.stream, openvdb::VersionId(openvdb::OPENVDB_LIBRARY_MAJOR_VERSION, openvdb::OPENVDB_LIBRARY_MINOR_VERSION), mFileVersion);
        openvdb::io::setDataCompression(in.stream, mCompression);
        openvdb::io::setGridBackgroundValuePtr(in.stream, &background);
        openvdb::util::NodeMask<3> mask;
        mask.load(in.stream);
        openvdb::io::readCompressedValues(in.stream, values, openvdb::util::NodeMask<3>::SIZE, mask, mHalf);
        if (!in.stream) throw std::runtime_error("its record ends early");
        return true;
    }

private:
    static constexpr unsigned kSizeBits = 20;  // a record's bytes: a leaf's at most ~4 KB
    static constexpr uint64_t kSizeMask = (uint64_t(1) << kSizeBits) - 1;
    struct Record {
        uint64_t key;  // treeKey(origin)
        uint64_t at;   // start << kSizeBits | size
    };
    static Record record(const std::array<int32_t, 3>& o, uint64_t start, uint64_t end)
    {
        return {treeKey(o[0], o[1], o[2]), start << kSizeBits | (end - start)};
    }
    // In the file's order, which is the tree's, the keys already ascend: runs held in that order too.
    void sortByKey()
    {
        const auto byKey = [](const Record& a, const Record& b) { return a.key < b.key; };
        if (!std::is_sorted(mRecords.begin(), mRecords.end(), byKey)) std::sort(mRecords.begin(), mRecords.end(), byKey);
    }
    // A stream over one record's bytes, a thread's own, reused.
    struct RecordStream {
        struct Buffer : std::streambuf {
            void over(char* b, size_t n) { setg(b, b, b + n); }
        };
        std::vector<char> bytes;
        Buffer buffer;
        std::istream stream{&buffer};
    };
    int mFd;
    uint32_t mFileVersion, mCompression;
    bool mHalf;
    bool mUsable = false;
    std::vector<Record> mRecords;
    std::vector<uint64_t> mAt;  // where records start, while some are held, until the last hold()
    // Every record held from the start; some, as hold() names them; or no more after the last hold().
    enum class Holding { All, Some, Done } mHolding = Holding::All;
};

namespace {

// OpenVDB's messages may span lines and start with their exception's class ("RuntimeError: "); the
// programs print one line per error, in words.
std::string oneLine(std::string s)
{
    for (char& c : s)
        if (c == '\n' || c == '\r') c = ' ';
    const size_t colon = s.find(": ");
    if (colon != std::string::npos && colon > 5 && s.compare(colon - 5, 5, "Error") == 0 &&
        s.find(' ') > colon)
        s.erase(0, colon + 2);
    return s;
}

std::string coordText(const openvdb::Coord& c)
{
    std::ostringstream s;
    s << "[" << c.x() << ", " << c.y() << ", " << c.z() << "]";
    return s.str();
}

// OpenVDB's LeafBuffer::doLoad() puts a fresh voxel array into the union that held the buffer's file
// position, then decompresses; when decompression throws, the out-of-core flag stays set over that
// array. From then on any access loads again and the destructor detaches from the "file", both
// reading the voxel array as the FileInfo it replaced: Tree::clear() crashes freeing garbage shared
// pointers. No public call clears the flag alone, so the broken buffer is swapped out of its leaf
// for an empty in-core one and kept, never destroyed, for the rest of the process (2 KB per damaged
// leaf met; a run stops at the first). Reachable from a static, so leak checkers stay quiet.
template <typename LeafT>
void parkBrokenBuffer(LeafT& leaf)
{
    static std::mutex mutex;
    static auto* parked = new std::vector<typename LeafT::Buffer*>;
    auto* empty = new typename LeafT::Buffer(openvdb::PartialCreate(), typename LeafT::ValueType(0));
    empty->swap(leaf.buffer());
    std::lock_guard<std::mutex> lock(mutex);
    parked->push_back(empty);
}

// Reads a leaf's voxels from the file (delayed loading) once; on failure the leaf is left safe to
// destroy (parkBrokenBuffer) and the error names the grid and the leaf. Callers serialise the first
// load of each leaf: a second thread waiting on OpenVDB's own lock would load the broken buffer.
template <typename LeafT>
void loadLeaf(LeafT& leaf, const std::string& gridName, const StoredLeaves* stored, const typename LeafT::ValueType& background)
{
    const char* what = nullptr;
    try {
        if (stored) {
            typename LeafT::Buffer read;
            if (stored->read(leaf.origin(), read.data(), background)) {
                leaf.swap(read);  // the on-disk buffer goes with `read`, unread
                return;
            }
        }
        // Without a delayed-load record (a topology read alone) the stored record is the only source.
        if (!leaf.buffer().isOutOfCore()) throw std::runtime_error("no stored record");
        leaf.buffer().data();
        return;
    } catch (const std::bad_alloc&) {
        what = "out of memory reading its voxels";
    } catch (const std::exception&) {
        what = "compressed data is damaged";
    }
    parkBrokenBuffer(leaf);
    throw InputError("grid '" + gridName + "', leaf " + coordText(leaf.origin()) + ": " + what);
}

// What OpenVDB's node reads ask of a stream over the file (io::Archive sets the same).
struct TopologyFormat {
    openvdb::VersionId library;
    uint32_t fileVersion = 0, compression = 0;
    bool half = false;
    openvdb::GridClass gridClass = openvdb::GRID_UNKNOWN;
};

struct TopologyStream {
    std::ifstream is;
    std::shared_ptr<openvdb::io::StreamMetadata> meta = std::make_shared<openvdb::io::StreamMetadata>();

    TopologyStream(const std::string& path, const TopologyFormat& format, const void* background)
        : is(path, std::ios::binary)
    {
        openvdb::io::setStreamMetadataPtr(is, meta, /*transfer=*/false);
        openvdb::io::setVersion(is, format.library, format.fileVersion);
        openvdb::io::setDataCompression(is, format.compression);
        openvdb::io::setHalfFloat(is, format.half);
        openvdb::io::setGridClass(is, format.gridClass);
        openvdb::io::setGridBackgroundValuePtr(is, background);
    }
    void seek(uint64_t pos)
    {
        is.seekg(std::streamoff(pos));
        if (!is) throw std::runtime_error("cannot seek to its topology");
    }
    template <typename T>
    T value()
    {
        T v{};
        is.read(reinterpret_cast<char*>(&v), sizeof v);
        return v;
    }
};

// Reads lower internal nodes, leaves' masks included, with OpenVDB's own InternalNode::readTopology on
// all threads, each from where the walk of the stored tree found its record starts and checked to end
// where it found the record ends. @throw std::runtime_error where one does not.
template <typename LowerT>
std::vector<std::unique_ptr<LowerT>> readLowerNodes(const std::string& path, const TopologyFormat& format,
                                                    const typename LowerT::ValueType& background,
                                                    const std::vector<openvdb::Coord>& origins,
                                                    const std::vector<std::array<uint64_t, 2>>& bytes)
{
    std::vector<std::unique_ptr<LowerT>> nodes(origins.size());
    std::atomic<bool> sound{true};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, origins.size(), 4), [&](const tbb::blocked_range<size_t>& r) {
        TopologyStream in(path, format, &background);
        for (size_t k = r.begin(); k != r.end() && sound; ++k) {
            in.seek(bytes[k][0]);
            nodes[k] = std::make_unique<LowerT>(openvdb::PartialCreate(), origins[k], background);
            nodes[k]->readTopology(in.is, format.half);
            if (!in.is || uint64_t(in.is.tellg()) != bytes[k][1]) sound = false;
        }
    });
    if (!sound) throw std::runtime_error("its topology ends early");
    return nodes;
}

// The lower internal nodes a distributed run's rank leaves on disk when it opens a file (Volume::open
// with a part of the ranks): each one's child mask and tile values, read from its record without its
// leaves, and where the record lies, so that the rank reads those its slabs sample once it knows
// them (readAround). The tree holds an inactive background tile in each one's place.
struct UnreadLowersBase {
    virtual ~UnreadLowersBase() = default;
    // Every leaf's origin in the file's order, and which of them the tree holds as read: [ownFirst, ownEnd).
    std::vector<std::array<int32_t, 3>> origins;
    size_t ownFirst = 0, ownEnd = 0;
    bool activeTiles = false;  // whether an unread node holds an active tile
    // The runs of `origins` read since (Volume::readAround): with [ownFirst, ownEnd), what the tree holds.
    std::vector<std::array<size_t, 2>> readRuns;
};

template <typename TreeT>
struct UnreadLowers final : UnreadLowersBase {
    using LowerT = typename TreeT::RootNodeType::ChildNodeType::ChildNodeType;
    using ValueT = typename TreeT::ValueType;
    struct Node {
        openvdb::Coord origin;
        uint64_t key = 0;  // treeKey(origin): the nodes stay in the file's order, which ascends in it
        std::array<uint64_t, 2> bytes{};
        typename LowerT::NodeMaskType childMask;
        std::unique_ptr<ValueT[]> values;
        bool activeTiles = false;
        size_t firstLeaf = 0;  // its first leaf's place in `origins`
    };
    std::string path;
    TopologyFormat format;
    ValueT background{};
    std::vector<Node> nodes;

    // The unread node that holds (x, y, z), or null.
    const Node* find(int32_t x, int32_t y, int32_t z) const
    {
        constexpr int32_t kMask = ~int32_t(LowerT::DIM - 1);
        const uint64_t key = treeKey(x & kMask, y & kMask, z & kMask);
        const auto it = std::lower_bound(nodes.begin(), nodes.end(), key, [](const Node& n, uint64_t k) { return n.key < k; });
        // The origin too: a point far outside the vertex keys' range (a tile's face) may share a key.
        const bool found = it != nodes.end() && it->origin == openvdb::Coord(x & kMask, y & kMask, z & kMask);
        return found ? &*it : nullptr;
    }
    bool probe(const std::array<int32_t, 3>& xyz, bool& leaf, double& value) const
    {
        const Node* n = find(xyz[0], xyz[1], xyz[2]);
        if (!n) return false;
        const openvdb::Index i = LowerT::coordToOffset(openvdb::Coord(xyz[0], xyz[1], xyz[2]));
        leaf = n->childMask.isOn(i);
        value = double(n->values[i]);
        return true;
    }
};

// Where a volume's grid comes from: a caller's grid (whole, kept), or a file's, whose voxels OpenVDB left
// on disk behind delayed-load records (through the file's mapping) or whose topology it read alone (the
// voxels come from the records the walk of the stored tree found, StoredLeaves).
enum class GridSource { Caller, DelayedLoad, TopologyAlone };

template <typename GridT>
class VolumeT final : public Volume {
public:
    using ValueT = typename GridT::ValueType;

    VolumeT(typename GridT::Ptr grid, VolumeInfo info, GridSource source, std::shared_ptr<UnreadLowersBase> unread = {})
        : mGrid(std::move(grid)), mUnreadLowers(std::static_pointer_cast<UnreadLowers<TreeT>>(std::move(unread)))
    {
        mInfo = std::move(info);
        mFromFile = source != GridSource::Caller;
        if (source == GridSource::DelayedLoad) {
            keepMappingAlive();
            trimInputMapping();  // the topology was read through the mapping
        }
    }

    void keepLeaves(const std::function<bool(const std::array<int32_t, 3>&)>& keep) override
    {
        if (!mFromFile) return;  // a caller's grid stays whole
        if (mUnwalked) {
            // A tree read in part keeps what it holds at most: the others are not asked about.
            std::vector<char> held;
            if (mUnreadLowers) {
                held.assign(mUnreadLowers->origins.size(), 0);
                std::fill(held.begin() + std::ptrdiff_t(mUnreadLowers->ownFirst), held.begin() + std::ptrdiff_t(mUnreadLowers->ownEnd), 1);
                for (const auto& run : mUnreadLowers->readRuns)
                    std::fill(held.begin() + std::ptrdiff_t(run[0]), held.begin() + std::ptrdiff_t(run[1]), 1);
            }
            KeptRecordsWalk walk(*mUnwalked);
            forEachStoredLeaf([&](const std::array<int32_t, 3>& origin, size_t i) {
                walk.leaf(origin, (held.empty() || held[i]) && (!keep || keep(origin)));
            });
            walk.walk();
            mUnwalked.reset();
        }
        if (keep) dropLeaves([&](const openvdb::Coord& o) { return !keep({o.x(), o.y(), o.z()}); });
        layOutInSweepOrder();
    }

    std::vector<std::array<int32_t, 3>> blocks(const Classifier& c, size_t part, size_t parts) const override
    {
        // A tree read in part lists what it holds: its part of the lower nodes is this part.
        if (mUnreadLowers) return collectBlocks(mGrid->tree(), c, 0, 1, absentProbe());
        return collectBlocks(mGrid->tree(), c, part, parts);
    }

    uint64_t tileShellBlocks(const Classifier& c) const override
    {
        return countTileShellBlocks(mGrid->tree(), c, mUnreadLowers ? absentProbe() : AbsentLowerProbe{});
    }

    void readAround(const std::array<int32_t, 3>* blocks, size_t count) override
    {
        if (!mUnreadLowers || mUnreadLowers->nodes.empty()) return;
        using LowerT = typename UnreadLowers<TreeT>::LowerT;
        using UpperT = typename TreeT::RootNodeType::ChildNodeType;
        UnreadLowers<TreeT>& unread = *mUnreadLowers;
        // The unread nodes these blocks' samples reach (a block's and its +x/+y/+z neighbours' leaves).
        std::vector<char> wanted(unread.nodes.size(), 0);
        for (size_t i = 0; i < count; ++i)
            for (int d = 0; d < 8; ++d) {
                const BlockOrigin leaf = sampledLeaf(blocks[i], d);
                if (const auto* n = unread.find(leaf[0], leaf[1], leaf[2])) wanted[size_t(n - unread.nodes.data())] = 1;
            }
        std::vector<openvdb::Coord> origins;
        std::vector<std::array<uint64_t, 2>> bytes;
        std::vector<size_t> which;
        for (size_t k = 0; k < wanted.size(); ++k)
            if (wanted[k]) {
                origins.push_back(unread.nodes[k].origin);
                bytes.push_back(unread.nodes[k].bytes);
                which.push_back(k);
            }
        std::vector<std::unique_ptr<LowerT>> read;
        try {
            read = readLowerNodes<LowerT>(unread.path, unread.format, unread.background, origins, bytes);
        } catch (const std::bad_alloc&) {
            throw InputError(mInfo.file + ": cannot read grid '" + mInfo.gridName + "' (out of memory reading its topology)");
        } catch (const std::exception& e) {
            throw InputError(mInfo.file + ": cannot read grid '" + mInfo.gridName + "' (" + oneLine(e.what()) + ")");
        }
        for (size_t j = 0; j < which.size(); ++j) {
            if (read[j]->getChildMask() != unread.nodes[which[j]].childMask)
                throw InputError(mInfo.file + ": truncated or damaged OpenVDB file (grid '" + mInfo.gridName +
                                 "': its topology changed while it was read)");
            UpperT* upper = mGrid->tree().root().template probeNode<UpperT>(origins[j]);
            const auto& node = unread.nodes[which[j]];
            unread.readRuns.push_back({node.firstLeaf, node.firstLeaf + node.childMask.countOn()});
            if (!upper || !upper->addChild(read[j].release()))
                throw InputError(mInfo.file + ": grid '" + mInfo.gridName + "': its topology is not the walked one");
        }
        if (mStored) mStored->hold(unread.origins, unread.readRuns, /*last=*/true);
        // What stays unread is never sampled: forgotten.
        unread.nodes.clear();
    }

    void sample(const std::array<int32_t, 3>& origin, BlockSamples& out, uint8_t reloadable) const override
    {
        loadLeaves(origin, reloadable);
        sampleUnchecked(origin, out);
    }

    // The first read of a leaf's voxels happens here, one thread per leaf (a lock stripe by origin),
    // for the up to 8 leaves the block's 9^3 samples touch: afterwards they are in memory and the
    // accessor's reads load nothing. A leaf that failed before is reported again.
    void loadLeaves(const std::array<int32_t, 3>& origin, uint8_t reloadable) const
    {
        for (int d = 0; d < 8; ++d) {
            const BlockOrigin l = sampledLeaf(origin, d);
            LeafT* leaf = mGrid->tree().probeLeaf(openvdb::Coord(l[0], l[1], l[2]));
            if (!leaf || !leaf->buffer().empty()) {
                if (mDamaged.load(std::memory_order_acquire)) throwDamaged();
                continue;
            }
            const openvdb::Coord o = leaf->origin();
            const uint32_t stripe = uint32_t(o.x()) * 73856093u ^ uint32_t(o.y()) * 19349663u ^ uint32_t(o.z()) * 83492791u;
            std::lock_guard<std::mutex> lock(mLoadMutex[stripe % kLoadStripes]);
            if (!leaf->buffer().empty()) continue;
            if ((reloadable >> d) & 1) {
                // A copy made while the voxels are still on disk keeps their place in the file.
                auto unread = std::make_unique<LeafT>(*leaf);
                std::lock_guard<std::mutex> parked(mUnreadMutex);
                mUnread[{o.x(), o.y(), o.z()}] = std::move(unread);
                mUnreadCount.store(mUnread.size(), std::memory_order_relaxed);
            }
            try {
                loadLeaf(*leaf, mInfo.gridName, mStored.get(), mGrid->background());
            } catch (const InputError& e) {
                std::lock_guard<std::mutex> g(mDamageMutex);
                if (!mDamaged.load()) mDamage = e.what();
                mDamaged.store(true, std::memory_order_release);
                throw;
            }
        }
    }

    [[noreturn]] void throwDamaged() const
    {
        std::lock_guard<std::mutex> g(mDamageMutex);
        throw InputError(mDamage);
    }

    // A block's 9^3 samples come from the up to 8 leaves at its origin and 8 voxels above it along
    // each axis: each is read straight from its buffer (or is one tile value), not voxel by voxel
    // through the tree. The accessor lives for one block, on a tree nothing restructures meanwhile, so
    // it is not registered with the tree: a registered one costs an insert and an erase in the tree's
    // concurrent accessor table per block, and a table grown that way is walked through TBB's
    // lazy-rehash markers when the tree is destroyed (undefined behaviour to -fsanitize=undefined).
    using Accessor = typename GridT::ConstUnsafeAccessor;
    void sampleUnchecked(const std::array<int32_t, 3>& origin, BlockSamples& out) const
    {
        Accessor acc = mGrid->getConstUnsafeAccessor();
        sampleLeaves(origin, out, acc, [&](const openvdb::Coord& at) -> const ValueT* {
            const LeafT* leaf = acc.probeConstLeaf(at);
            return leaf ? leaf->buffer().data() : nullptr;
        });
    }

    // A block sampled by a copy reader: a leaf still on disk is read from the copy `copied` finds, or
    // from a copy of its node that `read(leaf)` loads (a copy keeps its place in the file: loading it
    // leaves the volume's node on disk). Leaves are looked up in the tree, not through the accessor:
    // an accessor that caches a leaf reads its voxels (it keeps a pointer to them), which would load
    // the volume's own. Tiles are read through it.
    template <typename Copied, typename Read>
    void sampleCopies(const std::array<int32_t, 3>& origin, BlockSamples& out, Copied copied, Read read) const
    {
        Accessor acc = mGrid->getConstUnsafeAccessor();
        sampleLeaves(origin, out, acc, [&](const openvdb::Coord& at) -> const ValueT* {
            const LeafT* leaf = mGrid->tree().probeConstLeaf(at);
            if (!leaf) return nullptr;
            if (!leaf->buffer().empty()) return leaf->buffer().data();
            if (const ValueT* v = copied(*leaf)) return v;
            return read(*leaf);
        });
    }
    // The same with the voxels `valuesAt` gives for the leaf at a coordinate (null: a tile there,
    // read through `acc`).
    template <typename ValuesAt>
    void sampleLeaves(const std::array<int32_t, 3>& origin, BlockSamples& out, Accessor& acc,
                      ValuesAt valuesAt) const
    {
        out.origin = origin;
        constexpr int N = BlockSamples::N, D = int(LeafT::DIM);
        static_assert(N == D + 1, "a block spans one leaf and the first voxel layer of the next");
        if (((origin[0] | origin[1] | origin[2]) & (D - 1)) != 0)
            throw std::logic_error("a block origin off the leaf grid");  // collectBlocks makes none
        for (int d = 0; d < 8; ++d) {
            const int lo[3] = {(d & 1) * D, ((d >> 1) & 1) * D, ((d >> 2) & 1) * D};
            const int hi[3] = {lo[0] ? N : D, lo[1] ? N : D, lo[2] ? N : D};
            const openvdb::Coord at(origin[0] + lo[0], origin[1] + lo[1], origin[2] + lo[2]);
            if (const ValueT* v = valuesAt(at)) {
                for (int z = lo[2]; z < hi[2]; ++z)
                    for (int y = lo[1]; y < hi[1]; ++y)
                        for (int x = lo[0]; x < hi[0]; ++x)
                            out.at(x, y, z) = double(v[((x - lo[0]) * D + (y - lo[1])) * D + (z - lo[2])]);
            } else {
                const double tile = double(acc.getValue(at));
                for (int z = lo[2]; z < hi[2]; ++z)
                    for (int y = lo[1]; y < hi[1]; ++y)
                        for (int x = lo[0]; x < hi[0]; ++x) out.at(x, y, z) = tile;
            }
        }
        bool finite = true;
        for (const double v : out.values) finite &= std::isfinite(v);
        if (finite) return;
        for (int i = 0; i < N * N * N; ++i)
            if (!std::isfinite(out.values[i])) {
                const openvdb::Coord ijk(origin[0] + i % N, origin[1] + i / N % N, origin[2] + i / (N * N));
                std::ostringstream s;
                s << "voxel " << ijk << " of grid '" << mInfo.gridName << "' is " << out.values[i]
                  << " (NaN/Inf values are not allowed)";
                throw InputError(s.str());
            }
    }

    // One copy of a leaf still on disk, never read, keeps the file mapping alive (it is shared by the
    // buffers still on disk and is unmapped with the last of them) for as long as this volume lives,
    // so the ranges trimInputMapping() looks up once stay the file's: after an unmap, that address
    // range can come back as heap memory. With no leaf on disk (delayed loading off, or tiles only)
    // nothing holds the mapping, and trimming stays off.
    void keepMappingAlive()
    {
        for (auto it = mGrid->tree().cbeginLeaf(); it; ++it)
            if (it->buffer().isOutOfCore()) {
                mKeepsMapping = std::make_unique<typename GridT::TreeType::LeafNodeType>(*it.getLeaf());
                mHoldsMapping = true;
                return;
            }
    }

    // Deletes the leaves `drop` names, parent by parent (a tile of the background in a leaf's slot
    // deletes the leaf): nothing samples them, and on one rank of many they are most of the topology.
    template <typename Drop>
    void dropLeaves(Drop drop)
    {
        std::vector<ParentT*> parents;
        mGrid->tree().getNodes(parents);
        std::vector<openvdb::Index> gone;
        for (ParentT* parent : parents) {
            gone.clear();
            for (auto it = parent->cbeginChildOn(); it; ++it)
                if (drop(it->origin())) gone.push_back(it.pos());
            for (const openvdb::Index n : gone) parent->addTile(n, mGrid->background(), false);
        }
        ::malloc_trim(0);
    }

    // Leaf nodes come off the file in tree order (z fastest inside each internal node) but are deleted
    // in sweep order (z slowest, releaseLeaf), so a page of nodes emptied only near the end of the run
    // and the topology's resident memory would stay whole although its nodes were gone. Nodes made
    // again in sweep order free their pages as the sweep passes; each takes over its original's voxel
    // buffer, which for a leaf still on disk is its place in the file (a copy would allocate a new file
    // record and share the file's mapping once more, for every leaf). One row of parents along z at a
    // time: the originals of a row are whole parents, read one after another, so once they are deleted
    // and the heap consolidated, the next row's nodes fill those ranges in order, and the topology is
    // never held twice (the whole second copy was the peak of large runs kept to small outputs).
    void layOutInSweepOrder()
    {
        // Sorted by origins read once: the nodes themselves lie all over the heap.
        struct Placed {
            std::array<int32_t, 3> zyx;
            LeafT* leaf;
        };
        std::vector<Placed> leaves;
        leaves.reserve(mGrid->tree().leafCount());
        for (auto it = mGrid->tree().beginLeaf(); it; ++it) {
            const openvdb::Coord& o = it->origin();
            leaves.push_back({{o.z(), o.y(), o.x()}, it.getLeaf()});
        }
        std::sort(leaves.begin(), leaves.end(), [](const Placed& a, const Placed& b) { return a.zyx < b.zyx; });
        const auto row = [](const Placed& p) { return p.zyx[0] & ~int32_t(ParentT::DIM - 1); };
        constexpr size_t kAhead = 8;  // nodes requested ahead of the one remade: each is a cache miss
        std::vector<std::unique_ptr<LeafT>> remade;
        for (size_t begin = 0, end = 0; begin < leaves.size(); begin = end) {
            while (end < leaves.size() && row(leaves[end]) == row(leaves[begin])) ++end;
            remade.clear();
            for (size_t i = begin; i < end; ++i) {
                if (i + kAhead < end) {
                    const char* ahead = reinterpret_cast<const char*>(leaves[i + kAhead].leaf);
                    __builtin_prefetch(ahead);
                    __builtin_prefetch(ahead + 64);
                }
                LeafT& original = *leaves[i].leaf;
                auto node = std::make_unique<LeafT>(openvdb::PartialCreate(), original.origin(), mGrid->background());
                node->setValueMask(original.getValueMask());
                node->swap(original.buffer());
                remade.push_back(std::move(node));
            }
            for (auto& node : remade) mGrid->tree().addLeaf(node.release());  // deletes the original
            ::malloc_trim(0);
        }
    }

    void parkLeaf(const std::array<int32_t, 3>& o) override
    {
        if (!mFromFile) return;
        std::unique_ptr<LeafT> unread;
        {
            std::lock_guard<std::mutex> lock(mUnreadMutex);
            const auto it = mUnread.find(o);
            if (it == mUnread.end()) return;
            unread = std::move(it->second);
            mUnread.erase(it);
            mUnreadCount.store(mUnread.size(), std::memory_order_relaxed);
        }
        // The copy still on disk takes the loaded leaf's place (which is deleted), as releaseLeaf
        // puts a tile there: in the parent only, under the same lock.
        const openvdb::Coord ijk(o[0], o[1], o[2]);
        std::lock_guard<std::mutex> lock(mReleaseMutex);
        if (ParentT* parent = mGrid->tree().template probeNode<ParentT>(ijk))
            if (parent->isChildMaskOn(ParentT::coordToOffset(ijk))) {
                parent->addLeaf(unread.release());
                mParked.fetch_add(1, std::memory_order_relaxed);
            }
    }

    void releaseLeaf(const std::array<int32_t, 3>& o) override
    {
        if (!mFromFile) return;  // a caller's grid stays whole
        if (mUnreadCount.load(std::memory_order_relaxed) > 0) {
            std::lock_guard<std::mutex> lock(mUnreadMutex);
            mUnread.erase(o);
            mUnreadCount.store(mUnread.size(), std::memory_order_relaxed);
        }
        // The whole leaf goes, not just its voxels: the node and its mask are ~100 bytes a leaf, which
        // would otherwise stay to the end of the run. Nothing samples
        // this leaf again (blocks only sample leaves at or above their origin, and this block was the
        // last), so the parent's entry becomes an inactive background tile. Other threads may be
        // reading other entries of the same parent; only the writers are serialised.
        const openvdb::Coord ijk(o[0], o[1], o[2]);
        std::lock_guard<std::mutex> lock(mReleaseMutex);
        if (ParentT* parent = mGrid->tree().template probeNode<ParentT>(ijk)) {
            const openvdb::Index n = ParentT::coordToOffset(ijk);
            if (parent->isChildMaskOn(n)) parent->addTile(n, mGrid->background(), false);
        }
    }

    std::unique_ptr<CopyReader> copyReader() const override { return std::make_unique<Copies>(*this); }
    std::unique_ptr<CopyReader> privateCopyReader() const override { return std::make_unique<PrivateCopies>(*this); }

    std::array<double, 2> valueRange(size_t part, size_t parts) const override
    {
        // Loading the grid's own leaves would keep every voxel buffer at once: each leaf still on disk
        // is read into a copy of its node instead (from its record), or, where voxels are read through
        // OpenVDB's delayed loading, from a second delayed-loading copy of the grid whose leaves are
        // freed right after they are read. Either way the scan holds one leaf of memory at a time.
        typename GridT::Ptr copy = mGrid;
        if (mFromFile && !mStored) try {
            openvdb::io::File f(mInfo.file);
            f.setCopyMaxBytes(0);
            f.open(/*delayLoad=*/true);
            copy = openvdb::gridPtrCast<GridT>(f.readGrid(mInfo.gridName));
        } catch (const std::exception&) {
            copy = mGrid;  // not from a file (or unreadable now): scan in place
        }
        if (!copy) copy = mGrid;
        double lo = double(copy->background()), hi = lo;
        typename GridT::TreeType::ValueAllCIter tiles = copy->tree().cbeginValueAll();
        tiles.setMaxDepth(GridT::TreeType::ValueAllCIter::LEAF_DEPTH - 1);
        for (; tiles; ++tiles) {
            lo = std::min(lo, double(*tiles));
            hi = std::max(hi, double(*tiles));
        }
        std::vector<LeafT*> leaves;
        if (copy != mGrid) copy->tree().getNodes(leaves);
        else for (auto it = mGrid->tree().cbeginLeaf(); it; ++it) leaves.push_back(const_cast<LeafT*>(it.getLeaf()));
        const bool release = copy != mGrid;
        using Range = std::array<double, 2>;
        // A tree read in part holds this part's leaves and no others.
        if (mUnreadLowers) part = 0, parts = 1;
        const size_t first = leaves.size() * part / parts, last = leaves.size() * (part + 1) / parts;
        if (first >= last) return {lo, hi};
        if (mUnwalked) {
            // The part a shared walk checked is this part of the leaves in the file's order, which is
            // the tree's: checked, and any leaf of the part outside it walked here, before it is read.
            // A tree read in part holds one run of the file's leaves.
            const size_t shift = mUnreadLowers ? mUnreadLowers->ownFirst : 0;
            KeptRecordsWalk walk(*mUnwalked);
            forEachStoredLeaf([&](const std::array<int32_t, 3>& origin, size_t i) {
                walk.leaf(origin, i >= first + shift && i < last + shift);
            });
            walk.walk();
        }
        const Range r = tbb::parallel_reduce(
            tbb::blocked_range<size_t>(first, last, 64), Range{lo, hi},
            [&](const tbb::blocked_range<size_t>& br, Range acc) {
                for (size_t i = br.begin(); i != br.end(); ++i) {
                    LeafT* leaf = leaves[i];
                    std::optional<LeafT> copyOf;
                    if (leaf->buffer().empty()) {
                        if (!release) leaf = &copyOf.emplace(*leaf);  // the grid's own leaf stays on disk
                        loadLeaf(*leaf, mInfo.gridName, mStored.get(), mGrid->background());
                    }
                    const auto* v = leaf->buffer().data();
                    const auto mm = std::minmax_element(v, v + LeafT::SIZE);
                    acc = {std::min(acc[0], double(*mm.first)), std::max(acc[1], double(*mm.second))};
                    if (release) {
                        typename LeafT::Buffer empty(openvdb::PartialCreate(), copy->background());
                        leaves[i]->swap(empty);
                    }
                }
                return acc;
            },
            [](const Range& a, const Range& b) { return Range{std::min(a[0], b[0]), std::max(a[1], b[1])}; });
        return r;
    }

private:
    using TreeT = typename GridT::TreeType;
    using LeafT = typename GridT::TreeType::LeafNodeType;
    using ParentT = typename GridT::TreeType::RootNodeType::ChildNodeType::ChildNodeType;

    AbsentLowerProbe absentProbe() const
    {
        const UnreadLowers<TreeT>* unread = mUnreadLowers.get();
        return [unread](const std::array<int32_t, 3>& xyz, bool& leaf, double& value) { return unread->probe(xyz, leaf, value); };
    }
    // fn(origin, index) for every leaf the file stores, in the file's order (a tree read in part holds
    // some of them).
    template <typename Fn>
    void forEachStoredLeaf(Fn&& fn) const
    {
        if (mUnreadLowers) {
            for (size_t i = 0; i < mUnreadLowers->origins.size(); ++i) fn(mUnreadLowers->origins[i], i);
            return;
        }
        size_t i = 0;
        for (auto it = mGrid->tree().cbeginLeaf(); it; ++it, ++i) {
            const openvdb::Coord o = it->origin();
            fn(std::array<int32_t, 3>{o.x(), o.y(), o.z()}, i);
        }
    }

    typename GridT::Ptr mGrid;
    // Where the tree was read in part (a distributed run's rank): the lower nodes left unread.
    std::shared_ptr<UnreadLowers<TreeT>> mUnreadLowers;
    std::mutex mReleaseMutex;
    // Copies, still on disk, of the leaves a reloadable read loaded, until they are parked or released.
    mutable std::mutex mUnreadMutex;
    mutable std::map<std::array<int32_t, 3>, std::unique_ptr<LeafT>> mUnread;
    mutable std::atomic<size_t> mUnreadCount{0};
    // First loads of leaves (loadLeaves): a lock per stripe of leaf origins; the first damaged leaf's
    // message, repeated to every later sample so no block reads the emptied leaf as data.
    static constexpr size_t kLoadStripes = 64;
    mutable std::array<std::mutex, kLoadStripes> mLoadMutex;
    mutable std::atomic<bool> mDamaged{false};
    mutable std::mutex mDamageMutex;
    mutable std::string mDamage;
    std::unique_ptr<typename GridT::TreeType::LeafNodeType> mKeepsMapping;

    // Volume::CopyReader: each leaf a pass reads is loaded through a copy of its node made on the stack
    // (the volume's own node stays on disk) and its voxels kept in a slot of a pool until release() or
    // the reader's end. The reader numbers the volume's leaves in their transient data once, before
    // any read, and keeps each leaf's slot in an atomic array by that number: a read finds the voxels
    // without a lock or a map, and only a leaf's first load and its release take the lock of its
    // stripe of origins, as loadLeaves does. The slots come from large arrays and are reused: voxel
    // arrays freed one by one would leave the heap holed under the topology, and extraction's own
    // allocations would follow them there. A caller's grid is read as extraction reads it (its leaves
    // are never freed, and none of its nodes is numbered).
    class Copies final : public CopyReader {
    public:
        explicit Copies(const VolumeT& volume) : mVolume(volume)
        {
            if (!mVolume.mFromFile) return;
            uint32_t n = 0;
            for (auto it = mVolume.mGrid->tree().beginLeaf(); it; ++it) it->setTransientData(n++);
            mSlotOf.reset(new std::atomic<uint32_t>[n]());
        }
        ~Copies() override
        {
            if (!mVolume.mFromFile) return;
            for (auto it = mVolume.mGrid->tree().beginLeaf(); it; ++it) it->setTransientData(0);
        }

        void sample(const std::array<int32_t, 3>& origin, BlockSamples& out) override
        {
            if (!mSlotOf) return mVolume.sample(origin, out, 0);  // a caller's grid: as extraction reads it
            mVolume.sampleCopies(
                origin, out,
                [&](const LeafT& leaf) -> const ValueT* {
                    const uint32_t slot = mSlotOf[leaf.transientData()].load(std::memory_order_acquire);
                    return slot ? values(slot - 1) : nullptr;
                },
                [&](const LeafT& leaf) { return load(leaf); });
        }

        void release(const std::array<int32_t, 3>& o) override
        {
            if (!mSlotOf) return;
            const LeafT* leaf = mVolume.mGrid->tree().probeConstLeaf(openvdb::Coord(o[0], o[1], o[2]));
            if (!leaf || !leaf->buffer().empty()) return;
            uint32_t slot;
            {
                std::lock_guard<std::mutex> lock(stripe(leaf->origin()));
                slot = mSlotOf[leaf->transientData()].exchange(0, std::memory_order_acq_rel);
            }
            if (slot == 0) return;
            std::lock_guard<std::mutex> lock(mPoolMutex);
            mFree.push_back(slot - 1);
        }

    private:
        using Values = std::array<ValueT, LeafT::SIZE>;
        static constexpr uint32_t kSlotsPerArray = 256;
        static constexpr size_t kArrays = 1 << 16;  // 16.7M slots: more leaves than a pass keeps at once

        std::mutex& stripe(const openvdb::Coord& c)
        {
            const uint32_t h = uint32_t(c.x()) * 73856093u ^ uint32_t(c.y()) * 19349663u ^ uint32_t(c.z()) * 83492791u;
            return mStripes[h % kLoadStripes];
        }
        ValueT* values(uint32_t slot) const { return mArrays[slot / kSlotsPerArray][slot % kSlotsPerArray].data(); }

        uint32_t takeSlot()
        {
            std::lock_guard<std::mutex> lock(mPoolMutex);
            if (mFree.empty()) {
                if (mArrayCount == kArrays) throw std::bad_alloc();
                mArrays[mArrayCount] = std::make_unique<Values[]>(kSlotsPerArray);
                for (uint32_t i = kSlotsPerArray; i-- > 0;) mFree.push_back(uint32_t(mArrayCount) * kSlotsPerArray + i);
                ++mArrayCount;
            }
            const uint32_t slot = mFree.back();
            mFree.pop_back();
            return slot;
        }

        const ValueT* load(const LeafT& leaf)
        {
            std::atomic<uint32_t>& mine = mSlotOf[leaf.transientData()];
            std::lock_guard<std::mutex> lock(stripe(leaf.origin()));
            if (const uint32_t slot = mine.load(std::memory_order_acquire)) return values(slot - 1);  // loaded meanwhile
            // The copy's voxels go to the pool, and the copy with its array at once.
            LeafT copy(leaf);
            loadLeaf(copy, mVolume.mInfo.gridName, mVolume.mStored.get(), mVolume.mGrid->background());
            const uint32_t slot = takeSlot();
            std::copy_n(copy.buffer().data(), LeafT::SIZE, values(slot));
            mine.store(slot + 1, std::memory_order_release);
            return values(slot);
        }

        const VolumeT& mVolume;
        std::unique_ptr<std::atomic<uint32_t>[]> mSlotOf;  // slot + 1 of each leaf by its number; 0: none
        std::array<std::mutex, kLoadStripes> mStripes;
        std::mutex mPoolMutex;
        std::unique_ptr<std::unique_ptr<Values[]>[]> mArrays{new std::unique_ptr<Values[]>[kArrays]};
        size_t mArrayCount = 0;
        std::vector<uint32_t> mFree;
    };

    // Copies of the leaves one reader's blocks read, kept by origin until the reader goes: a run of
    // 64 blocks reads about two hundred leaves, so a list searched from its end (the leaves a block
    // reads were mostly read by the block before) serves.
    class PrivateCopies final : public CopyReader {
    public:
        explicit PrivateCopies(const VolumeT& volume) : mVolume(volume) {}

        void sample(const std::array<int32_t, 3>& origin, BlockSamples& out) override
        {
            if (!mVolume.mFromFile) return mVolume.sample(origin, out, 0);
            mVolume.sampleCopies(
                origin, out,
                [&](const LeafT& leaf) -> const ValueT* {
                    for (size_t i = mCopies.size(); i-- > 0;)
                        if (mCopies[i].first == leaf.origin()) return mCopies[i].second->buffer().data();
                    return nullptr;
                },
                [&](const LeafT& leaf) {
                    auto copy = std::make_unique<LeafT>(leaf);
                    loadLeaf(*copy, mVolume.mInfo.gridName, mVolume.mStored.get(), mVolume.mGrid->background());
                    mCopies.emplace_back(leaf.origin(), std::move(copy));
                    return mCopies.back().second->buffer().data();
                });
        }
        void release(const std::array<int32_t, 3>&) override {}

    private:
        const VolumeT& mVolume;
        std::vector<std::pair<openvdb::Coord, std::unique_ptr<LeafT>>> mCopies;
    };
};

Affine affineOf(const openvdb::math::Transform& xform)
{
    // OpenVDB multiplies row vectors: world = index * M, translation in row 3.
    const openvdb::Mat4d m = xform.baseMap()->getAffineMap()->getMat4();
    Affine a;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) a.m[r * 4 + c] = m(c, r);
        a.m[r * 4 + 3] = m(3, r);
    }
    return a;
}

// Topology figures for the memory estimate; walks nodes, never a voxel buffer.
template <typename GridT>
void topologyInfo(const GridT& g, VolumeInfo& info)
{
    const auto& tree = g.tree();
    info.leafCount = tree.leafCount();
    info.activeVoxels = g.activeVoxelCount();
    info.topologyBytes = tree.memUsage();
    info.valueBytes = sizeof(typename GridT::ValueType);
    // Leaves per z-layer from the leaves' parents' child masks (a leaf's slot gives its z), without a
    // visit to each of millions of leaves.
    using LowerT = typename GridT::TreeType::RootNodeType::ChildNodeType::ChildNodeType;
    constexpr openvdb::Index kSide = LowerT::DIM / LowerT::ChildNodeType::DIM;
    std::vector<const LowerT*> parents;
    tree.getNodes(parents);
    std::map<int32_t, uint64_t> perLayer;
    for (const LowerT* parent : parents) {
        uint64_t counts[kSide] = {};
        for (auto it = parent->cbeginChildOn(); it; ++it) ++counts[it.pos() % kSide];
        for (openvdb::Index k = 0; k < kSide; ++k)
            if (counts[k]) perLayer[parent->origin().z() + int32_t(k * LowerT::ChildNodeType::DIM)] += counts[k];
    }
    for (const auto& layer : perLayer) info.maxLeavesPerLayer = std::max(info.maxLeavesPerLayer, layer.second);
}

// The tree's topology as Tree::readTopology reads it, with the lower internal nodes (and their
// millions of leaves) read by OpenVDB's own InternalNode::readTopology on all threads, each from where
// the walk of the stored tree found it starts (VdbGridLayout::lowerNodes); the root and the upper
// nodes, a few kilobytes, are read here in order as RootNode and InternalNode read them. Part `part` of
// `parts` (a distributed run's rank) reads the lower nodes of that share of the leaves, in the file's
// order, and of the others only their masks and tile values (returned; null for the whole tree): the
// leaves' allocation is most of a topology's read, and a rank's slabs sample a few of the nodes.
template <typename GridT>
std::shared_ptr<UnreadLowersBase> readTopologyOnAllThreads(GridT& grid, const std::string& path, const TopologyFormat& format,
                                                           const VdbGridLayout& layout, size_t part, size_t parts)
{
    using TreeT = typename GridT::TreeType;
    using RootT = typename TreeT::RootNodeType;
    using UpperT = typename RootT::ChildNodeType;
    using LowerT = typename UpperT::ChildNodeType;
    using ValueT = typename GridT::ValueType;
    const bool half = format.half;

    TopologyStream top(path, format, nullptr);
    top.seek(layout.topologyPos);
    top.template value<int32_t>();  // the buffer count (TreeBase::readTopology): 1, checked by the walk
    const ValueT background = top.template value<ValueT>();
    openvdb::io::setGridBackgroundValuePtr(top.is, &background);
    auto tree = std::make_shared<TreeT>(background);
    const auto tiles = top.template value<openvdb::Index32>(), children = top.template value<openvdb::Index32>();
    for (openvdb::Index32 n = 0; n < tiles; ++n) {
        const auto xyz = top.template value<std::array<openvdb::Int32, 3>>();
        const ValueT value = top.template value<ValueT>();
        const bool active = top.template value<bool>();
        tree->root().addTile(openvdb::Coord(xyz[0], xyz[1], xyz[2]), value, active);
    }
    std::vector<std::unique_ptr<UpperT>> uppers;
    std::vector<UpperT*> parents;
    std::vector<openvdb::Coord> origins;
    parents.reserve(layout.lowerNodes.size());
    origins.reserve(layout.lowerNodes.size());
    std::unique_ptr<ValueT[]> values(new ValueT[UpperT::NUM_VALUES]);
    for (openvdb::Index32 c = 0; c < children && top.is; ++c) {
        const auto xyz = top.template value<std::array<openvdb::Int32, 3>>();
        uppers.push_back(std::make_unique<UpperT>(openvdb::PartialCreate(), openvdb::Coord(xyz[0], xyz[1], xyz[2]), background));
        UpperT& upper = *uppers.back();
        typename UpperT::NodeMaskType childMask, valueMask;
        childMask.load(top.is);
        valueMask.load(top.is);
        openvdb::io::readCompressedValues(top.is, values.get(), UpperT::NUM_VALUES, valueMask, half);
        for (openvdb::Index n = 0; n < UpperT::NUM_VALUES; ++n)
            if (!childMask.isOn(n)) upper.addTile(n, values[n], valueMask.isOn(n));
        bool first = true;
        for (auto it = childMask.beginOn(); it; ++it, first = false) {
            const size_t k = origins.size();
            if (k >= layout.lowerNodes.size() || (first && uint64_t(top.is.tellg()) != layout.lowerNodes[k][0]))
                throw std::runtime_error("its topology is not the walked one");
            parents.push_back(&upper);
            origins.push_back(upper.offsetToGlobalCoord(it.pos()));
            top.seek(layout.lowerNodes[k][1]);
        }
    }
    if (!top.is || origins.size() != layout.lowerNodes.size()) throw std::runtime_error("its topology ends early");

    std::shared_ptr<UnreadLowers<TreeT>> unread;
    std::vector<size_t> own(origins.size());
    for (size_t k = 0; k < own.size(); ++k) own[k] = k;
    if (parts > 1) {
        // Every node's masks and tile values, as InternalNode::readTopology reads them before its leaves.
        unread = std::make_shared<UnreadLowers<TreeT>>();
        unread->path = path;
        unread->format = format;
        unread->background = background;
        unread->nodes.resize(origins.size());
        std::atomic<bool> sound{true};
        tbb::parallel_for(tbb::blocked_range<size_t>(0, origins.size(), 4), [&](const tbb::blocked_range<size_t>& r) {
            TopologyStream in(path, format, &background);
            typename LowerT::NodeMaskType valueMask;
            for (size_t k = r.begin(); k != r.end() && sound; ++k) {
                auto& n = unread->nodes[k];
                n.origin = origins[k];
                n.key = treeKey(n.origin.x(), n.origin.y(), n.origin.z());
                n.bytes = layout.lowerNodes[k];
                in.seek(n.bytes[0]);
                n.childMask.load(in.is);
                valueMask.load(in.is);
                n.values.reset(new ValueT[LowerT::NUM_VALUES]);
                openvdb::io::readCompressedValues(in.is, n.values.get(), LowerT::NUM_VALUES, valueMask, half);
                n.activeTiles = !valueMask.isOff();
                if (!in.is) sound = false;
            }
        });
        if (!sound) throw std::runtime_error("its topology ends early");
        // This part: a run of the nodes in the file's order, each weighing its leaves and one more (its
        // tiles), the nodes whose weight starts in this part's share.
        uint64_t weight = 0, leaves = 0;
        for (const auto& n : unread->nodes) {
            leaves += n.childMask.countOn();
            weight += n.childMask.countOn() + 1;
        }
        const uint64_t first = weight * part / parts, end = weight * (part + 1) / parts;
        own.clear();
        unread->origins.reserve(leaves);
        for (size_t k = 0, at = 0; k < unread->nodes.size(); at += unread->nodes[k].childMask.countOn() + 1, ++k) {
            const bool mine = at >= first && at < end;
            unread->nodes[k].firstLeaf = unread->origins.size();
            if (mine) {
                if (own.empty()) unread->ownFirst = unread->origins.size();
                own.push_back(k);
            }
            for (auto it = unread->nodes[k].childMask.beginOn(); it; ++it) {
                openvdb::Coord local;
                LowerT::offsetToLocalCoord(it.pos(), local);
                const openvdb::Coord o = origins[k] + (local << LowerT::ChildNodeType::TOTAL);
                unread->origins.push_back({o.x(), o.y(), o.z()});
            }
            if (mine) unread->ownEnd = unread->origins.size();
        }
        if (own.empty()) unread->ownFirst = unread->ownEnd = 0;
    }
    std::vector<openvdb::Coord> ownOrigins;
    std::vector<std::array<uint64_t, 2>> ownBytes;
    for (size_t k : own) {
        ownOrigins.push_back(origins[k]);
        ownBytes.push_back(layout.lowerNodes[k]);
    }
    std::vector<std::unique_ptr<LowerT>> read = readLowerNodes<LowerT>(path, format, background, ownOrigins, ownBytes);
    for (size_t j = 0; j < own.size(); ++j) {
        if (unread && read[j]->getChildMask() != unread->nodes[own[j]].childMask)
            throw std::runtime_error("its topology is not the walked one");
        parents[own[j]]->addChild(read[j].release());
    }
    if (unread) {
        // What stays unread: the nodes of the other parts, in the file's order (find() searches it).
        std::vector<typename UnreadLowers<TreeT>::Node> rest;
        size_t next = 0;
        for (size_t k = 0; k < unread->nodes.size(); ++k) {
            if (next < own.size() && own[next] == k) {
                ++next;
                continue;
            }
            unread->activeTiles = unread->activeTiles || unread->nodes[k].activeTiles;
            rest.push_back(std::move(unread->nodes[k]));
        }
        const auto byKey = [](const auto& a, const auto& b) { return a.key < b.key; };
        if (!std::is_sorted(rest.begin(), rest.end(), byKey)) std::sort(rest.begin(), rest.end(), byKey);
        unread->nodes = std::move(rest);
    }
    for (auto& upper : uppers) tree->root().addChild(upper.release());
    grid.setTree(tree);
    return unread;
}

// A grid with the metadata and transform OpenVDB read when it listed the file's grids (`meta`), and the
// topology read from `topologyPos` as io::Archive::readGrid reads it, but without the leaves'
// delayed-load records: OpenVDB 10 offers no read of the topology alone, and those records (an
// allocation and a reference to the file's mapping per leaf, about 130 MB of the gyroid's peak)
// serve only delayed loading, while this reader reads each leaf's voxels from the record the walk of
// the stored tree found (StoredLeaves). The leaves come without voxel buffers (empty() until read).
// Part `part` of `parts`: that share of the lower nodes, the others left unread (`unread`).
openvdb::GridBase::Ptr readTopologyAlone(const std::string& path, const openvdb::io::File& file,
                                         const openvdb::GridBase& meta, const VdbGridLayout& layout, size_t part,
                                         size_t parts, std::shared_ptr<UnreadLowersBase>& unread)
{
    openvdb::GridBase::Ptr grid = openvdb::GridBase::createGrid(meta.type());
    grid->setSaveFloatAsHalf(meta.saveFloatAsHalf());
    for (auto it = meta.beginMeta(); it != meta.endMeta(); ++it)  // the per-leaf sizes serve the records' reads only
        if (it->first != openvdb::GridBase::META_FILE_DELAYED_LOAD) grid->insertMeta(it->first, *it->second);
    grid->setTransform(meta.transform().copy());
    const TopologyFormat format{file.libraryVersion(), file.fileVersion(), layout.compression, grid->saveFloatAsHalf(),
                                grid->getGridClass()};
    if (auto f = openvdb::GridBase::grid<openvdb::FloatGrid>(grid))
        unread = readTopologyOnAllThreads(*f, path, format, layout, part, parts);
    else if (auto d = openvdb::GridBase::grid<openvdb::DoubleGrid>(grid))
        unread = readTopologyOnAllThreads(*d, path, format, layout, part, parts);
    else throw std::runtime_error("not a float or double grid");
    return grid;
}

bool isScalar(const openvdb::GridBase& g) { return g.isType<openvdb::FloatGrid>() || g.isType<openvdb::DoubleGrid>(); }

// The grid a file's reader means when none is named: the first level set (a file with a surface in it
// is about that surface), else the grid named "density" (Houdini's and Blender's smoke, whose first
// grid may be a colour channel such as color.x), else the first float or double grid. Decided on the
// grids' metadata alone: no tree is read. Null when the file has no float or double grid.
openvdb::GridBase::ConstPtr defaultGrid(const openvdb::GridPtrVec& metas)
{
    for (const auto& g : metas)
        if (isScalar(*g) && g->getGridClass() == openvdb::GRID_LEVEL_SET) return g;
    for (const auto& g : metas)
        if (isScalar(*g) && g->getName() == "density") return g;
    for (const auto& g : metas)
        if (isScalar(*g)) return g;
    return nullptr;
}

// What both entry points share once the grid is in hand: the info the pipeline needs, and the
// checks that need the topology (never a voxel buffer).
// A tree read in part (`unread`) counts the file's leaves and tiles, not only its own.
std::unique_ptr<Volume> wrapGrid(openvdb::GridBase::Ptr grid, const std::string& label, GridSource source,
                                 double checkSeconds = 0.0, std::shared_ptr<UnreadLowersBase> unread = {})
{
    VolumeInfo info;
    info.file = label;
    info.checkSeconds = checkSeconds;
    info.gridName = grid->getName();
    info.valueType = grid->valueType();
    info.levelSet = grid->getGridClass() == openvdb::GRID_LEVEL_SET;
    info.indexToWorld = affineOf(grid->transform());
    if (std::abs(info.indexToWorld.determinant()) < 1e-300)
        throw InputError(label + ": grid '" + info.gridName + "' has a singular transform");

    std::unique_ptr<Volume> vol;
    if (auto f = openvdb::GridBase::grid<openvdb::FloatGrid>(grid)) {
        info.background = f->background();
        topologyInfo(*f, info);
        if (unread) info.leafCount = unread->origins.size();
        vol = std::make_unique<VolumeT<openvdb::FloatGrid>>(f, info, source, unread);
    } else if (auto d = openvdb::GridBase::grid<openvdb::DoubleGrid>(grid)) {
        info.background = d->background();
        topologyInfo(*d, info);
        if (unread) info.leafCount = unread->origins.size();
        vol = std::make_unique<VolumeT<openvdb::DoubleGrid>>(d, info, source, unread);
    } else {
        throw InputError(label + ": grid '" + info.gridName + "' is not a float or double grid");
    }
    if (!std::isfinite(info.background))
        throw InputError(label + ": grid '" + info.gridName + "' has a non-finite background value");
    if (info.activeVoxels == 0 && info.leafCount == 0 && !(unread && unread->activeTiles))
        throw InputError(label + ": grid '" + info.gridName + "' is empty (no active voxels)");
    // The topology's own box (leaves and active tiles), before any voxel is read.
    openvdb::CoordBBox box;
    if (grid->baseTree().evalLeafBoundingBox(box)) {
        const int32_t mn[3] = {box.min().x(), box.min().y(), box.min().z()};
        const int32_t mx[3] = {box.max().x(), box.max().y(), box.max().z()};
        try {
            checkIndexBox(mn, mx, "the grid's leaves and active tiles span the index box");
        } catch (const InputError& e) {
            throw InputError(label + ": grid '" + info.gridName + "': " + e.what());
        }
    }
    return vol;
}


} // namespace

void Volume::trimInputMapping() const
{
    if (!mHoldsMapping) return;
    // The mapping exists from the open on and stays put while this volume lives (the volume keeps it
    // alive, see layOutInSweepOrder): /proc/self/maps is read once.
    std::call_once(mMappedOnce, [this] {
        char resolved[PATH_MAX];
        if (!::realpath(mInfo.file.c_str(), resolved)) return;
        const std::string target = resolved;
        std::ifstream maps("/proc/self/maps");
        std::string line;
        while (std::getline(maps, line)) {
            // "start-end perms offset dev inode   path"
            if (line.size() < target.size() || line.compare(line.size() - target.size(), target.size(), target) != 0) continue;
            unsigned long start = 0, end = 0;
            if (std::sscanf(line.c_str(), "%lx-%lx", &start, &end) == 2 && end > start) mMapped.push_back({start, end - start});
        }
    });
    for (const auto& [start, length] : mMapped) ::madvise(reinterpret_cast<void*>(start), length, MADV_DONTNEED);
}

namespace {

// Calls a distributed run's agreement once per open, failed or not: a process that stops before its walk
// ends (a missing file, a damaged record) has no say, and the others go on instead of waiting for it; its
// error reaches them at the pipeline's next agreement.
class AgreeOnce {
public:
    explicit AgreeOnce(const TreeAgreement& agreement) : mAgreement(agreement) {}
    ~AgreeOnce()
    {
        try {
            agree(false, false, 0);
        } catch (...) {  // an error is already on its way out; the run ends with it
        }
    }
    AgreeOnce(const AgreeOnce&) = delete;
    AgreeOnce& operator=(const AgreeOnce&) = delete;
    bool agree(bool walked, bool sound, uint64_t digest)
    {
        if (!mAgreement.agree || mDone) return sound;
        mDone = true;
        return mAgreement.agree(walked, sound, digest);
    }

private:
    const TreeAgreement& mAgreement;
    bool mDone = false;
};

} // namespace

std::unique_ptr<Volume> Volume::open(const std::string& path, const std::string& gridName, const TreeAgreement& agreement)
{
    static std::once_flag init;
    std::call_once(init, [] { openvdb::initialize(); });
    AgreeOnce agreeOnce(agreement);

    if (!std::ifstream(path, std::ios::binary).good())
        throw InputError(path + ": cannot open file for reading (missing or unreadable)");
    // OpenVDB trusts the offsets a file states; a truncated file would send it into a loop.
    VdbFileEntries entries = checkVdbFileStructure(path);

    openvdb::io::File file(path);
    openvdb::GridPtrVecPtr metas;
    try {
        file.setCopyMaxBytes(0);  // read the file in place rather than through a private copy
        file.open(/*delayLoad=*/true);
        metas = readGridHeaders(path, entries, file);  // without decoding the delayed-load tables again
        if (!metas) metas = file.readAllGridMetadata();
    } catch (const std::bad_alloc&) {
        throw InputError(path + ": not a readable OpenVDB file (out of memory reading its metadata)");
    } catch (const std::exception& e) {
        throw InputError(path + ": not a readable OpenVDB file (" + oneLine(e.what()) + ")");
    }
    if (!metas || metas->empty()) throw InputError(path + ": the file holds no grids");

    openvdb::GridBase::ConstPtr meta;
    if (gridName.empty()) {
        meta = defaultGrid(*metas);
        if (!meta) {
            std::string names;
            for (const auto& g : *metas) names += (names.empty() ? "" : ", ") + g->getName() + " (" + g->valueType() + ")";
            throw InputError(path + ": no float or double grid in the file (grids: " + names + ")");
        }
    } else {
        for (const auto& g : *metas)
            if (g->getName() == gridName) { meta = g; break; }
        if (!meta) {
            std::string names;
            for (const auto& g : *metas) names += (names.empty() ? "" : ", ") + g->getName();
            throw InputError(path + ": no grid named '" + gridName + "' (grids: " + names + ")");
        }
        if (!isScalar(*meta)) {
            std::string scalars;
            for (const auto& g : *metas)
                if (isScalar(*g)) scalars += (scalars.empty() ? "" : ", ") + g->getName();
            throw InputError(path + ": grid '" + gridName + "' has value type " + meta->valueType() +
                             "; only float and double grids can be meshed (" +
                             (scalars.empty() ? "the file has none" : "float/double grids: " + scalars) + ")");
        }
    }

    // Before the topology is read: the bounding box the file states, and the transform.
    try {
        checkGridMetadata(*meta);
        checkTransform(meta->transform());
    } catch (const InputError& e) {
        throw InputError(path + ": grid '" + meta->getName() + "' " + e.what());
    }

    // Before OpenVDB reads the tree: its topology and every leaf's record, as stored.
    const Stopwatch check;
    LeafWalkShare share{agreement.part, agreement.parts,
                        [&](bool sound, uint64_t digest) { return agreeOnce.agree(true, sound, digest); }};
    VdbGridLayout layout = checkVdbGridData(path, entries, meta->getName(), agreement.agree ? &share : nullptr);
    agreeOnce.agree(false, false, 0);  // a tree this walk does not cover has no say
    for (auto& g : entries.grids) g.delayed.reset();  // walked: OpenVDB reads the topology next
    const double checkSeconds = check.seconds();

    // Where the walk found every leaf's record, the voxels are read from there and OpenVDB reads the
    // topology alone.
    const bool fromRecords = layout.checked && layout.topologyPos != 0 && !layout.recordStarts.empty() &&
                             layout.fileVersion >= openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION &&
                             openvdb::io::Archive::isDelayedLoadingEnabled();
    // A distributed run's process reads its share of the lower nodes (readAround reads the others it needs).
    const size_t part = agreement.agree ? agreement.part : 0, parts = agreement.agree ? agreement.parts : 1;
    std::shared_ptr<UnreadLowersBase> unread;
    openvdb::GridBase::Ptr grid;
    const Stopwatch topology;
    try {
        grid = fromRecords ? readTopologyAlone(path, file, *meta, layout, part, parts, unread) : file.readGrid(meta->getName());
    } catch (const std::bad_alloc&) {
        throw InputError(path + ": cannot read grid '" + meta->getName() + "' (out of memory reading its topology)");
    } catch (const std::exception& e) {
        throw InputError(path + ": cannot read grid '" + meta->getName() + "' (" + oneLine(e.what()) + ")");
    }
    if (!grid) throw InputError(path + ": cannot read grid '" + meta->getName() + "'");
    const size_t leavesRead = unread ? unread->origins.size() : size_t(grid->baseTree().leafCount());
    if (layout.checked && (leavesRead != layout.leafCount || (unread && grid->baseTree().leafCount() != unread->ownEnd - unread->ownFirst)))
        throw InputError(path + ": truncated or damaged OpenVDB file (grid '" + meta->getName() + "': " +
                         std::to_string(leavesRead) + " leaves read, " + std::to_string(layout.leafCount) + " stored)");
    try {
        checkTransform(grid->transform());
    } catch (const InputError& e) {
        throw InputError(path + ": grid '" + meta->getName() + "' " + e.what());
    }

    const double topologySeconds = fromRecords ? topology.seconds() : 0.0;
    std::unique_ptr<Volume> volume =
        wrapGrid(grid, path, fromRecords ? GridSource::TopologyAlone : GridSource::DelayedLoad, checkSeconds, unread);
    volume->mInfo.topologySeconds = topologySeconds;
    volume->mUnwalked = layout.unwalked;
    if (layout.checked && !layout.recordStarts.empty()) {
        // Only where OpenVDB left voxels on disk (delayed loading may be switched off). The tree lists
        // its leaves in the file's order; where the walk kept their origins, they must agree (where it
        // shared them out, keepLeaves checks the order before any read, and the tree's are collected).
        const std::vector<std::array<int32_t, 3>>& walked = layout.leafOrigins;
        std::vector<std::array<int32_t, 3>> origins;
        bool onDisk = false, same = true;
        const auto collect = [&](const auto& tree) {
            size_t i = 0;
            for (auto it = tree.cbeginLeaf(); it; ++it, ++i) {
                const std::array<int32_t, 3> o{it->origin().x(), it->origin().y(), it->origin().z()};
                if (walked.empty()) origins.push_back(o);
                else same = same && i < walked.size() && walked[i] == o;
                onDisk = onDisk || it->buffer().empty();
            }
            same = same && (walked.empty() || i == walked.size());
        };
        if (unread) {
            // Read in part: the leaves, all on disk, as the walked topology lists them.
            onDisk = true;
        } else {
            if (walked.empty()) origins.reserve(layout.leafCount);
            if (auto f = openvdb::GridBase::grid<openvdb::FloatGrid>(grid)) collect(f->tree());
            else if (auto d = openvdb::GridBase::grid<openvdb::DoubleGrid>(grid)) collect(d->tree());
        }
        if (onDisk && same) {
            // Read in part: the records of the leaves the tree holds (readAround adds those it reads).
            auto stored = std::make_shared<StoredLeaves>(path, layout, unread ? unread->origins : walked.empty() ? origins : walked,
                                                         unread ? &layout.recordStarts : nullptr);
            if (unread) stored->hold(unread->origins, {{unread->ownFirst, unread->ownEnd}});
            if (stored->usable() && layout.leafCount > 0) volume->mStored = std::move(stored);
        }
    }
    if (fromRecords && layout.leafCount > 0 && !volume->mStored)  // a topology read alone has no other source of voxels
        throw InputError(path + ": truncated or damaged OpenVDB file (grid '" + meta->getName() +
                         "': its leaves are not the stored ones)");
    return volume;
}

std::unique_ptr<Volume> Volume::fromGrid(openvdb::GridBase::ConstPtr grid, const std::string& label)
{
    static std::once_flag init;
    std::call_once(init, [] { openvdb::initialize(); });
    if (!grid) throw InputError(label + ": no grid");
    if (!isScalar(*grid))
        throw InputError(label + ": grid '" + grid->getName() + "' has value type " + grid->valueType() +
                         "; only float and double grids can be meshed");
    try {
        checkTransform(grid->transform());
    } catch (const InputError& e) {
        throw InputError(label + ": grid '" + grid->getName() + "' " + e.what());
    }
    // Never written to: a caller's grid is only read (releaseLeaf is a no-op for it).
    return wrapGrid(openvdb::ConstPtrCast<openvdb::GridBase>(grid), label, GridSource::Caller);
}

} // namespace vdb_isosimp

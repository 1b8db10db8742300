// Input checks done before any voxel is read, so a hostile or damaged file fails in milliseconds with
// one clear line instead of hanging, crashing or running for hours first:
//  - the file's own structure (header, grid descriptors and the byte ranges they claim), which
//    OpenVDB trusts blindly: a truncated file otherwise sends its reader into a loop over garbage;
//  - the grid's index bounding box, from the file's metadata, against the range vertex keys can name;
//  - the transform: linear, finite, invertible.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <openvdb/openvdb.h>


namespace vdb_isosimp {

// A grid's per-leaf codes and chunk sizes from its delayed-load metadata (input_checks.cpp).
struct DelayedLoadSizes;

// One grid as the file's descriptor states it.
struct VdbGridEntry {
    std::string uniqueName;  // as stored: the name plus a suffix when names repeat
    std::string plain;       // without the suffix
    std::string name;        // plain, printable
    std::string type;        // tree type, "_HalfFloat" appended when stored as half floats
    std::string parent;      // instance parent (unique name); empty for a grid with its own tree
    uint64_t gridPos = 0, blockPos = 0, endPos = 0;
    bool streamed = false;   // in a file without grid offsets: positions found by walking the grids
    // Its delayed-load metadata as checkVdbFileStructure decoded it (null: none, or not kept there),
    // which checkVdbGridData walks the grid's records with instead of decoding it again.
    std::shared_ptr<const DelayedLoadSizes> delayed;
    // What listing the grids reads (readGridHeaders), as checkVdbFileStructure walked it: where the
    // metadata map starts (its count), where its "file_delayed_load" item lies ([delayedBegin,
    // delayedEnd), both 0 without one) and where the transform ends (0: not walked, a transform other
    // than a linear map, or a file without grid offsets).
    uint64_t metaPos = 0, delayedBegin = 0, delayedEnd = 0, headerEnd = 0;
};

// Where a file's grids lie, as checkVdbFileStructure found them.
struct VdbFileEntries {
    uint32_t version = 0;
    bool checkable = false;  // false only for files that cannot be walked without being consumed (pipes)
    std::vector<VdbGridEntry> grids;
};

// Walks the header, the metadata and the grid descriptors of a .vdb file and checks that every
// grid's data lies inside the file, and every grid's metadata and transform (which OpenVDB reads when
// it lists the grids) inside its grid. In a file written without grid offsets (a stream), which
// OpenVDB reads whole when it opens it, every grid's tree is walked too (as checkVdbGridData does);
// such a file with a grid of another type than float or double is refused, as are file formats older
// than 222. Returns where the grids lie, for checkVdbGridData (a stream's trees are walked once here).
// @throw InputError naming the file ("truncated or damaged OpenVDB file ...", or what is refused).
VdbFileEntries checkVdbFileStructure(const std::string& path);

// The grids' metadata and transforms, without their trees, as io::File::readAllGridMetadata lists
// them (in the order of their names, the descriptors' map), read from the bytes the walk found, but
// without decoding the delayed-load tables: OpenVDB decodes each (a byte and a size per leaf, about
// 0.2 s on a 2 GB file) and then drops it, and checkVdbFileStructure has decoded it already. Null
// where the walk did not find every grid's header (no grid offsets, a transform not a linear map):
// the caller lists them with OpenVDB then. `file` is the open file (its format versions).
// @throw what OpenVDB's metadata and transform reads throw.
openvdb::GridPtrVecPtr readGridHeaders(const std::string& path, const VdbFileEntries& entries,
                                       const openvdb::io::File& file);

// The stored records of a grid's leaves (input_checks.cpp).
struct LeafRecords;

// What checkVdbGridData learned about a grid's tree.
struct VdbGridLayout {
    bool checked = false;                              // false: a layout left to OpenVDB
    size_t leafCount = 0;
    std::vector<std::array<int32_t, 3>> leafOrigins;   // in file order (moved to `unwalked` where there is one)
    std::vector<uint16_t> leafActive;                  // (during the walk) active voxels per leaf
    // A hash of the leaves' origins, active counts and record positions: two copies of one stored tree
    // have the same digest (the processes of a distributed run compare them: Volume::open).
    uint64_t digest = 0;
    // Where each leaf's record (its value mask, then its values) starts, in file order, and last where
    // the records end; and how the values are stored. The voxel reads decode the records from there
    // (volume_reader.cpp). Empty where the walk did not learn them.
    std::vector<uint64_t> recordStarts;
    // Where the grid's topology starts in the file, after its compression flags, metadata and
    // transform; 0 for an instance (its tree is its parent's) and for a file written as a stream.
    uint64_t topologyPos = 0;
    // Where each lower internal node's topology (its masks, tile values and leaves' masks) starts and
    // ends, in file order: what OpenVDB's own node reads take on all threads (volume_reader.cpp).
    std::vector<std::array<uint64_t, 2>> lowerNodes;
    uint32_t fileVersion = 0, compression = 0;
    bool half = false;
    // Where the processes of a distributed run shared the walk (LeafWalkShare): the records of the
    // leaves this process did not walk, for KeptRecordsWalk once it knows which leaves it reads.
    std::shared_ptr<const LeafRecords> unwalked;
};

// The processes of a distributed run share the walk of a grid's leaf records: where the file says where
// every record starts, each walks part `part` of `parts` of them (in file order: the part of the leaves
// a fog grid's value-range scan reads, Volume::valueRange), and one call learns whether every part was
// sound (and compares the processes' digests: copies of one stored tree). If not, each walks every
// record as one process does, which names the first fault the same way everywhere. A process still
// walks every record it decompresses (KeptRecordsWalk): another process's walk of its own copy vouches
// for nothing on this one.
struct LeafWalkShare {
    size_t part = 0, parts = 1;
    // This process's verdict on its part and its digest in; true when every part was sound. Called
    // once per check; where the records cannot be split, with the whole walk's verdict.
    std::function<bool(bool sound, uint64_t digest)> allSound;
};

// Walks one float or double grid's stored tree before OpenVDB reads it: the topology node by node
// (counts against the bytes that hold them, node origins, tile-value chunks), then every leaf's
// record (value mask, compression code, chunk size, the blosc header's sizes and block offsets or
// the zlib header) against the leaf's expected size, and the per-leaf sizes of the delayed-load
// metadata against the records. OpenVDB trusts all of these: a wrong one makes it allocate what the
// file says, read past a buffer in c-blosc, or loop over garbage. What only decompression can find
// (damaged compressed bytes) is left to the voxel reads (volume_reader.cpp).
// @throw InputError: "PATH: truncated or damaged OpenVDB file (grid 'NAME': ...)", or for one leaf
// "PATH: grid 'NAME', leaf [x, y, z]: compressed data is damaged (...)".
// With a share, this process walks its part of the leaf records (LeafWalkShare).
VdbGridLayout checkVdbGridData(const std::string& path, const VdbFileEntries& entries, const std::string& gridName,
                               const LeafWalkShare* share = nullptr);

// Walks the records of the leaves a process reads that its part of a shared walk left out, before it
// decompresses them: every leaf of the tree as OpenVDB read it goes through leaf(), in the tree's order
// (the file's: the records keep no origins, only a hash of them in that order), then walk().
class KeptRecordsWalk {
public:
    explicit KeptRecordsWalk(const LeafRecords& records) : mRecords(records) {}
    void leaf(const std::array<int32_t, 3>& origin, bool reads);
    // @throw InputError as checkVdbGridData does for a damaged leaf record, or for a tree whose leaves
    // are not the stored ones in the stored order.
    void walk();

private:
    const LeafRecords& mRecords;
    size_t mLeaves = 0;
    uint64_t mOrder = 0;
    std::vector<std::pair<size_t, std::array<int32_t, 3>>> mRead;  // file index, origin
};

// Index bounding box [min, max] of the active voxels: every coordinate must leave room for the block
// one leaf below and the sample one voxel above within the vertex-key range (edge_key.h).
// @throw InputError (without the file name) describing the box and the supported range.
void checkIndexBox(const int32_t min[3], const int32_t max[3], const char* what);

// The bounding box the file's metadata states for a grid (file_bbox_min/max), when present.
void checkGridMetadata(const openvdb::GridBase& meta);

// Linear, all coefficients finite, invertible. @throw InputError (without the file name).
void checkTransform(const openvdb::math::Transform& xform);

} // namespace vdb_isosimp

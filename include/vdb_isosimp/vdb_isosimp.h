// vdb_isosimp: iso-surface extraction with on-the-fly simplification from OpenVDB volumes.
//
// One call for most users:
//     vdb_isosimp::Result r = vdb_isosimp::simplifyFile("smoke.vdb", options);
// reads a float/double grid with delayed loading, extracts its iso-surface with Marching Cubes block by
// block (8^3 cells, z/y/x order) and decimates it with quadric edge collapse while extracting, so the
// full-resolution surface never exists in memory. The result is a closed, oriented (counter-clockwise
// seen from outside) triangle mesh in world space.
//
// Also: simplifyGrid() for a grid already in memory, and variants of both that hand the final mesh to
// a MeshSink in pieces instead of returning it. Write the mesh with writeMesh() (mesh_writer.h).
// Installed as a CMake package: find_package(vdb_isosimp CONFIG), target vdb_isosimp::vdb_isosimp,
// #include <vdb_isosimp/vdb_isosimp.h>.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <openvdb/version.h>

#include "errors.h"
#include "mesh.h"
#include "mesh_writer.h"

namespace openvdb {
OPENVDB_USE_VERSION_NAMESPACE
namespace OPENVDB_VERSION_NAME {
class GridBase;
}
} // namespace openvdb

namespace vdb_isosimp {

struct LevelOfDetail;

struct Options {
    // Grid to mesh; empty: the file's first level-set grid, else the grid named "density", else its
    // first float or double grid (only the grids' metadata is read to choose).
    std::string gridName;
    // Iso-value. Unset: 0 for level sets, the midpoint of the grid's value range for other grids.
    std::optional<double> iso;
    // Decimation rate R in (0, 1]: faces kept / faces of the full-resolution surface. Default 0.2.
    double ratio = 0.2;
    // If > 0: keep this many faces instead. A counting pass over the blocks turns it into R: exact, or
    // on volumes of more than 2 * countSampleRuns runs of 64 blocks a stratified sample of at least
    // countSampleRuns runs, whose R is raised by three standard errors of its estimate (at least 1 %)
    // so the slabs keep enough; the final pass takes the rest off. 0: always exact. Default 4096.
    uint64_t targetFaces = 0;
    uint64_t countSampleRuns = 4096;
    // B: the intermediate mesh holds at most R*F + B faces; a pass runs every B/2 new faces and leaves
    // B/2 of room for collapses deferred to a later pass. Bigger: better quality, more memory. Default 100000.
    uint64_t batchFaces = 100000;
    // R_i: rate of the initial phase (paper, section 4.2) used while R < R_i. Default 0.5.
    double initialRatio = 0.5;
    // Worker threads; 0: all cores. The output does not depend on it.
    int threads = 0;
    // Refuse to start (MemoryBudgetError naming the file) when the peak memory estimated from the
    // grid's topology exceeds this many bytes; checked on the opened grid before any voxel is read
    // (and again with the surface along tile faces once the iso-value is known). 0: no limit.
    uint64_t maxMemoryBytes = 0;
    // Most blocks (8^3 cells) per slab: the blocks are cut into the fewest slabs of at most this many,
    // rounded up to a power of two (at most 1024 slabs), the independent pieces of work that threads
    // and MPI ranks share, joined by a fixed merge tree (a power of two halves exactly at every node).
    // Changes the output (more slabs: more seams, each decimated when its two sides join); the output
    // never depends on threads or ranks. Default 2048.
    uint64_t blocksPerSlab = 2048;
    // A node of the merge tree holding at least this many faces is decimated to the rate without the
    // deferral room, and a join of two such nodes retires the interior of the joined surface: faces far
    // from every seam are written to the output part of the mesh (12 bytes a face and 12 a point) and
    // leave the decimator (~120 bytes a face), so the run holds bands around the seams instead of the
    // whole decimated surface. Changes the output where it applies; 0: never (each node keeps its room
    // and its interior up to the final pass). A LOD chain's levels retire like a single-rate run: they
    // part at the slabs, before any join. Default 50000.
    uint64_t retireAboveFaces = 50000;
    // If > 0: after the final decimation, closed components whose area is below this many world
    // units squared are removed (floaters); Report::componentsPruned counts them. Default 0 (none).
    double minComponentArea = 0.0;
    // E > 0: an error bound in world units. No collapse (in the passes during extraction or in the
    // final one) may move the surface by more than E, estimated as the larger of sqrt(cost / weight),
    // the area-weighted RMS distance of the new vertex from the planes of the faces merged into it
    // (each face weighs its area, at least 0.25 of a voxel face), and the surface's local change around
    // the edge (faces before against after, both ways) added to the drift its ends already carry. With
    // ratio or targetFaces as well, whichever stops first wins; ratio = 0 with E > 0 means E alone.
    // 0 (default): no bound.
    double maxError = 0.0;
    // LOD chain: decreasing rates in (0, 1], e.g. {0.2, 0.05, 0.01}. Non-empty: one run makes every
    // level: extraction decimates at lods[0] (level 0 is the mesh of a run at ratio lods[0]), each
    // slab continues from a copy of one level to the next rate, every level is joined and finished
    // like a single-rate run and handed to onLevel as soon as it is made (so a caller can write it and
    // let it go), finest first; the Result holds the last level and
    // Report::levels one entry per level. ratio is ignored; targetFaces must be 0.
    std::vector<double> lods;
    std::function<void(const LevelOfDetail&)> onLevel;
    // Grids sampled trilinearly at every output vertex (float, double: one value; vec3: three), each in
    // its own index space (world -> index by its own transform), after the final pass; the values go
    // to Mesh::attributes in this order. File input only (simplifyFile); every name is checked before
    // any work (InputError for a missing or non-numeric grid).
    std::vector<std::string> attributes;
    // W > 0: the decimator also keeps the first attribute's detail (a float or double grid): each face
    // adds an attribute quadric (Hoppe 1999) and a collapse costs its geometric error plus W^2 times
    // the attribute's error, W in attribute units per world unit. 0 (default): geometry only.
    double attributeWeight = 0.0;
};

// Physical memory, lowered to the cgroup (container) limit when there is one; 0 if unknown. A budget
// for Options::maxMemoryBytes.
uint64_t machineMemoryBytes();

// One decimation pass, for plots of the intermediate mesh (paper, figures 5 and 9).
struct DecimationRecord {
    uint64_t facesGenerated = 0;   // F_g: faces extracted so far
    uint64_t facesBefore = 0, facesAfter = 0;
    uint64_t uncontractible = 0;   // F_u before the pass
    uint64_t target = 0;           // F_t
    uint32_t slab = 0;             // which slab's integrator ran it (the final pass: slab 0)
};

// One level of a LOD chain (Options::lods), as the report sees it.
struct LevelReport {
    double ratio = 0.0;
    uint64_t facesTarget = 0, facesOut = 0, vertsOut = 0;
    double maxErrorAccepted = 0.0;  // largest estimated displacement of a collapse up to this level
    double seconds = 0.0;           // time since the run started when the level was ready
    std::string stoppedBy;          // as Report::stoppedBy, for this level
};

// Why a run's decimation stopped where it did, as Report::stoppedBy says it: "target" when the face
// count is at most 1 % (or 2 faces) above the target, else "error bound" when `boundHeld`: some edge
// left was refused by Options::maxError alone (its topology allows the collapse and a placement keeps
// the faces valid; the bound alone sets no face target), else "topology" (every collapse left would
// change the surface's genus or fold faces over: a sponge of pores, a cloud of closed droplets, or a
// surface already as coarse as it can be).
std::string stopReason(uint64_t facesOut, uint64_t facesTarget, bool boundHeld);

// What a run did; `--report` writes it as JSON.
struct Report {
    std::string file, grid, valueType, gridClass;
    double iso = 0.0;
    bool isoDefaulted = false;
    double ratio = 0.0;               // effective R
    uint64_t blocks = 0;
    uint64_t facesFull = 0;           // F: faces of the full-resolution surface
    uint64_t facesTarget = 0;
    uint64_t facesOut = 0, vertsOut = 0;
    uint64_t decimations = 0;
    uint64_t maxIntermediateFaces = 0;
    uint64_t maxUncontractibleFaces = 0;
    uint64_t componentsDropped = 0;   // small closed components removed to reach the face target
    uint64_t componentsPruned = 0;    // closed components below Options::minComponentArea removed
    // Faces set aside before the final pass, never collapsed again (Options::retireAboveFaces); the
    // clean-up that drops small components to reach the target may still remove some.
    uint64_t facesRetired = 0;
    uint64_t unfinalizedAtEnd = 0;    // vertices never finalised by the block rule (0 when correct)
    // The decimation's work, every level of a chain included: queue entries popped, of which entries
    // of a dead vertex, stale entries queued again and collapses attempted; and the collapses they made
    // (not the zero-area clean-up's). The same numbers for any thread or rank count.
    uint64_t queuePops = 0, queueDead = 0, queueStale = 0, collapseAttempts = 0, collapses = 0;
    double seconds = 0.0;
    double secondsSlabs = 0.0;        // of which: extraction and decimation of the slabs (parallel)
    double secondsFinal = 0.0;        // of which: the final pass on the whole surface and the result's copy
    double secondsFinalParallel = 0.0;  // of secondsFinal: on all threads (the zero-area scan, the mesh's collection)
    double secondsCount = 0.0;        // of which: counting the full-resolution faces for a face target
    // A face target's count: every this-many-th run of 64 blocks was counted (1: all, exact), and R was
    // raised by this fraction of the estimate (0 when exact).
    uint64_t countStride = 1;
    double countMargin = 0.0;
    double secondsLayout = 0.0;       // of which: laying out this process's leaves (each rank its own)
    // Of `seconds`, the set-up: opening the file (its checks and topology), choosing the iso-value and
    // listing the blocks (with ranks, each lists its share and merges the shares), cutting them into
    // slabs; and counting which blocks read which leaf (each rank over its own blocks).
    double secondsOpen = 0.0, secondsBlocks = 0.0, secondsCut = 0.0, secondsSamplers = 0.0;
    // Of secondsBlocks, with ranks: exchanging the shares of the block list and merging them, in
    // this many rounds (ceil(log2 ranks)).
    double secondsBlocksMerge = 0.0;
    uint64_t blockMergeRounds = 0;
    double secondsCheck = 0.0;        // of secondsOpen: walking the file's records before OpenVDB reads it
    double secondsTopology = 0.0;     // of secondsOpen: reading the topology, its lower nodes on all threads
    double peakRssMb = 0.0;
    uint64_t slabs = 0;               // independent pieces of work (Options::blocksPerSlab)
    // A distributed run (mpirun): how many processes, and each one's seconds and peak memory.
    uint64_t ranks = 1;
    std::vector<double> rankSeconds, rankPeakRssMb, rankBytesSent;
    // Each rank's CPU seconds until its leaves are laid out, less those spent waiting in the ranks'
    // collectives: its share of the set-up, for the scaling model of docs/scale.md.
    std::vector<double> rankSetupCpuSeconds;
    // Seconds of each node of the merge tree this process made: a slab's extraction (end = first + 1)
    // or the join of two siblings; for the scaling model of docs/scale.md.
    struct TreeNode {
        uint32_t firstSlab = 0, endSlab = 0;
        double seconds = 0.0;
    };
    std::vector<TreeNode> tree;
    // Largest estimated surface displacement (Options::maxError's estimate) of any collapse made, in
    // world units: with a bound, at most Options::maxError.
    double maxErrorAccepted = 0.0;
    std::vector<LevelReport> levels;  // Options::lods: one per level, finest first
    std::vector<DecimationRecord> trace;
    // "target", "error bound" or "topology" (stopReason): whether the face count asked for was met,
    // and if not, what kept the surface above it. A chain's is its last level's.
    std::string stoppedBy;
};

// A level of a LOD chain, handed to Options::onLevel: valid only during the call.
struct LevelOfDetail {
    size_t index = 0;      // 0: the finest
    const Mesh& mesh;      // with its attributes (Options::attributes)
    const LevelReport& report;
    const Report& run;     // the run so far: grid, iso, faces_full, ... (levels up to this one)
};

// One field of the report, named as the program's --report JSON and the Python dict name it.
struct ReportField {
    enum class Kind { Text, Integer, Real, Reals };
    std::string name;
    Kind kind = Kind::Text;
    std::string text;
    uint64_t integer = 0;
    double real = 0.0;
    std::vector<double> reals;  // Kind::Reals: a list, one entry per rank
};

// Every field of a run's report, in the order --report writes them; the one list the program's JSON
// and the Python dict are both made from. `options` gives the batch size the run used.
std::vector<ReportField> reportFields(const Report& report, const Options& options);

// Progress and cancellation, called from the in-order stage (never concurrently).
class Progress {
public:
    virtual ~Progress() = default;
    // fraction of blocks done in [0,1], faces currently kept. Return false to cancel (throws Cancelled).
    virtual bool update(double fraction, uint64_t facesKept) = 0;
    // With a face target (Options::targetFaces) the blocks are counted before any is extracted:
    // fraction of them counted in [0,1]. Return false to cancel (throws Cancelled). By default
    // update(0, 0): nothing extracted yet, and a cancel is honoured during the count too.
    virtual bool counting(double /*fraction*/) { return update(0.0, 0); }
};

struct Result {
    Mesh mesh;
    Report report;
};

// Runs the whole pipeline on a file.
// @throw InputError, EmptySurfaceError, Cancelled (errors.h); messages name the file and the problem.
Result simplifyFile(const std::string& vdbPath, const Options& options, Progress* progress = nullptr);

// Runs the whole pipeline on a grid in memory: a float or double grid with a linear transform (a
// pyopenvdb grid, a grid built by the caller). The grid is only read, never changed. Options::gridName
// is ignored; Report::file is empty and error messages name the grid instead of a file.
// @throw InputError, EmptySurfaceError, Cancelled (errors.h).
Result simplifyGrid(const openvdb::GridBase& grid, const Options& options, Progress* progress = nullptr);

// Receives the final mesh in pieces: begin() once with the finished report (vertsOut, facesOut give
// the counts), then vertices() until all points are delivered, then triangles() (indices into the
// points, counter-clockwise seen from outside), then attribute() once per sampled grid, then end().
// Each piece's storage is valid only during the call. Lets a caller convert or upload the mesh without
// holding a second full copy of it.
class MeshSink {
public:
    virtual ~MeshSink() = default;
    virtual void begin(const Report& /*report*/) {}
    virtual void vertices(const std::array<float, 3>* points, size_t count) = 0;
    virtual void triangles(const std::array<uint32_t, 3>* triangles, size_t count) = 0;
    // Each sampled attribute (Options::attributes) whole, after the triangles; ignored by default.
    virtual void attribute(const VertexAttribute& /*values*/) {}
    virtual void end() {}
};

// Streaming variants: the mesh goes to `sink` (pieces of at most 65536 elements), the report is returned.
Report simplifyFile(const std::string& vdbPath, const Options& options, MeshSink& sink, Progress* progress = nullptr);
Report simplifyGrid(const openvdb::GridBase& grid, const Options& options, MeshSink& sink,
                    Progress* progress = nullptr);

} // namespace vdb_isosimp

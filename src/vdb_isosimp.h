// vdb_isosimp: iso-surface extraction with on-the-fly simplification from OpenVDB volumes.
//
// One call for most users:
//     vdb_isosimp::Result r = vdb_isosimp::simplifyFile("smoke.vdb", options);
// reads a float/double grid with delayed loading, extracts its iso-surface with Marching Cubes block by
// block (8^3 cells, z/y/x order) and decimates it with quadric edge collapse while extracting, so the
// full-resolution surface never exists in memory. The result is a closed, oriented (counter-clockwise
// seen from outside) triangle mesh in world space.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "mesh.h"

namespace vdb_isosimp {

struct Options {
    // Grid to mesh; empty: the first float or double grid of the file.
    std::string gridName;
    // Iso-value. Unset: 0 for level sets, the midpoint of the grid's value range for other grids.
    std::optional<double> iso;
    // Decimation rate R in (0, 1]: faces kept / faces of the full-resolution surface. Default 0.2.
    double ratio = 0.2;
    // If > 0: keep this many faces instead (an exact counting pass over the blocks turns it into R).
    uint64_t targetFaces = 0;
    // B: new faces extracted between two decimations. Bigger: better quality, more memory. Default 100000.
    uint64_t batchFaces = 100000;
    // R_i: rate of the initial phase (paper, section 4.2) used while R < R_i. Default 0.5.
    double initialRatio = 0.5;
    // Worker threads; 0: all cores. The output does not depend on it.
    int threads = 0;
};

// One decimation pass, for plots of the intermediate mesh (paper, figures 5 and 9).
struct DecimationRecord {
    uint64_t facesGenerated = 0;   // F_g: faces extracted so far
    uint64_t facesBefore = 0, facesAfter = 0;
    uint64_t uncontractible = 0;   // F_u before the pass
    uint64_t target = 0;           // F_t
};

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
    uint64_t unfinalizedAtEnd = 0;    // vertices never finalised by the block rule (0 when correct)
    double seconds = 0.0;
    double peakRssMb = 0.0;
    std::vector<DecimationRecord> trace;
};

// Progress and cancellation, called from the in-order stage (never concurrently).
class Progress {
public:
    virtual ~Progress() = default;
    // fraction of blocks done in [0,1], faces currently kept. Return false to cancel (throws Cancelled).
    virtual bool update(double fraction, uint64_t facesKept) = 0;
};

struct Result {
    Mesh mesh;
    Report report;
};

// Runs the whole pipeline on a file.
// @throw InputError, EmptySurfaceError, Cancelled (errors.h); messages name the file and the problem.
Result simplifyFile(const std::string& vdbPath, const Options& options, Progress* progress = nullptr);

} // namespace vdb_isosimp

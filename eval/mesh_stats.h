// Topology and geometry statistics of an indexed triangle mesh, computed directly on the index
// arrays (no half-edge structure, so meshes OpenMesh would refuse are measured as they are).
#pragma once
#include "vdb_isosimp/mesh.h"

#include <cstddef>

namespace vdb_isosimp::eval {

struct MeshStats {
    size_t vertices = 0;            // points in the array
    size_t faces = 0;               // triangles in the array
    size_t referencedVertices = 0;  // points used by at least one triangle
    size_t edges = 0;               // distinct undirected edges {a,b}, a != b
    // Every edge falls in exactly one of: boundary (1 face), manifold (2 faces),
    // non-manifold (>2 faces). A triangle with a repeated index uses its edge once per side.
    size_t boundaryEdges = 0;
    size_t nonManifoldEdges = 0;
    size_t misorientedEdges = 0;    // 2-face edges whose two faces traverse it in the same direction
    size_t nonManifoldVertices = 0; // incident faces form more than one fan (edge-connected group)
    size_t zeroAreaFaces = 0;       // area <= zeroAreaEps (also: repeated indices)
    size_t components = 0;          // groups of faces connected through shared vertices
    long eulerCharacteristic = 0;   // referencedVertices - edges + faces
    double signedVolume = 0;        // sum of signed tetrahedra (positive for outward CCW faces)
    double area = 0;
    // Percentiles (nearest lower rank) of the per-triangle smallest angle, in degrees;
    // degenerate triangles count as 0.
    double minAngleP1 = 0, minAngleP5 = 0, minAngleP50 = 0;
    // Bounding box of the referenced vertices (all zero for a mesh without faces).
    double bboxMin[3] = {0, 0, 0}, bboxMax[3] = {0, 0, 0};
    double bboxDiagonal = 0;

    // Watertight: every edge has exactly two faces.
    bool closed() const { return faces > 0 && boundaryEdges == 0 && nonManifoldEdges == 0; }
    // Two-manifold (possibly with boundary): no edge with >2 faces, no vertex with several fans.
    bool manifold() const { return nonManifoldEdges == 0 && nonManifoldVertices == 0; }
    // Consistently oriented: neighbouring faces traverse their shared edges in opposite directions.
    bool oriented() const { return misorientedEdges == 0; }
};

// zeroAreaEps is an absolute area (squared length units); 0 means "exactly zero", evaluated as the
// cross product of the edge vectors in double. The signed volume is taken relative to the bounding
// box centre, which is exact for closed meshes and limits cancellation for far-off coordinates.
// Runs in parallel (TBB); results do not depend on the thread count.
// Throws std::invalid_argument if a triangle references a vertex index out of range.
MeshStats computeMeshStats(const Mesh& mesh, double zeroAreaEps = 0);

} // namespace vdb_isosimp::eval

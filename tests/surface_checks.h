// The invariants every simplified surface is held to in the end-to-end tests: closed, manifold,
// consistently oriented, outward, and (below R = 1) no face of zero area, meaning at most 1e-12 of the
// squared bounding-box diagonal.
#pragma once
#include "mesh_stats.h"
#include "vdb_isosimp/mesh.h"

#include <gtest/gtest.h>

#include <string>

namespace vdb_isosimp::testing {

inline void expectClosedOutward(const Mesh& m, bool allowZeroArea, const std::string& what)
{
    const double diagonal = eval::computeMeshStats(m).bboxDiagonal;
    const eval::MeshStats s = eval::computeMeshStats(m, 1e-12 * diagonal * diagonal);
    EXPECT_TRUE(s.closed()) << what << ": boundary " << s.boundaryEdges << " non-manifold edges " << s.nonManifoldEdges;
    EXPECT_TRUE(s.manifold()) << what << ": non-manifold vertices " << s.nonManifoldVertices;
    EXPECT_TRUE(s.oriented()) << what << ": misoriented edges " << s.misorientedEdges;
    EXPECT_GT(s.signedVolume, 0) << what << ": normals point inward";
    if (!allowZeroArea) {
        EXPECT_EQ(s.zeroAreaFaces, 0u) << what;
    }
}

} // namespace vdb_isosimp::testing

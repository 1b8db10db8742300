#include "reference_decimate.h"

#include "eval_openmesh.h"

#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

namespace vdb_isosimp::eval {

namespace {

// The same surface numbered by itself: vertices by position, each face from its lowest corner, faces
// in order. OpenMesh breaks ties between equal costs by handle (the flat faces of a solid tie all
// over), so its result moves with the input's numbering alone: on a rotated tetrahedron at R = 0.05 by
// 13 % of RMS between two numberings of one surface (docs/fidelity.md). Numbered this way, the
// reference depends on the surface, not on how the mesh under test happens to number it.
Mesh canonical(const Mesh& m)
{
    std::vector<uint32_t> order(m.points.size());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return m.points[a] < m.points[b]; });
    std::vector<uint32_t> number(order.size());
    Mesh c;
    c.points.reserve(order.size());
    for (uint32_t i = 0; i < order.size(); ++i) {
        number[order[i]] = i;
        c.points.push_back(m.points[order[i]]);
    }
    c.triangles.reserve(m.triangles.size());
    for (std::array<uint32_t, 3> t : m.triangles) {
        for (uint32_t& v : t) v = number[v];
        std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());  // keeps the orientation
        c.triangles.push_back(t);
    }
    std::sort(c.triangles.begin(), c.triangles.end());
    return c;
}

} // namespace

Mesh decimateWithOpenMesh(const Mesh& full, size_t targetFaces, size_t* refusedFaces) {
    size_t refused = 0;
    TriMesh om = toOpenMesh(canonical(full), refused);
    if (refusedFaces) *refusedFaces = refused;
    else if (refused > 0)
        throw std::runtime_error("decimateWithOpenMesh: OpenMesh refused " + std::to_string(refused) + " of " +
                                 std::to_string(full.triangles.size()) + " input faces");

    // Status flags mark collapsed elements; face normals are the reference of the flip test.
    // Requesting the normals here also keeps ModNormalFlippingT from logging that it had to.
    om.request_vertex_status();
    om.request_edge_status();
    om.request_face_status();
    om.request_face_normals();
    om.update_face_normals();

    using Decimater = OpenMesh::Decimater::DecimaterT<TriMesh>;
    Decimater decimater(om);
    // Quadric module left at its defaults: no max error (so the face target alone decides when to
    // stop) and non-binary, i.e. it provides the collapse order, as in QSlim.
    OpenMesh::Decimater::ModQuadricT<TriMesh>::Handle quadric;
    decimater.add(quadric);
    // Binary module at its default 90 degree limit: refuses only collapses that fold a face over.
    OpenMesh::Decimater::ModNormalFlippingT<TriMesh>::Handle flipping;
    decimater.add(flipping);
    if (!decimater.initialize()) throw std::runtime_error("decimateWithOpenMesh: decimater setup failed");

    if (targetFaces < om.n_faces()) decimater.decimate_to_faces(0, targetFaces);
    om.garbage_collection();
    return fromOpenMesh(om);
}

} // namespace vdb_isosimp::eval

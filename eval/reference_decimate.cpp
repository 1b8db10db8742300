#include "reference_decimate.h"

#include "eval_openmesh.h"

#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <stdexcept>
#include <string>

namespace vdb_isosimp::eval {

Mesh decimateWithOpenMesh(const Mesh& full, size_t targetFaces, size_t* refusedFaces) {
    size_t refused = 0;
    TriMesh om = toOpenMesh(full, refused);
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

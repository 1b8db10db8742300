#include "mesh_io.h"

#include "eval_openmesh.h"

#include <OpenMesh/Core/IO/importer/BaseImporter.hh>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <stdexcept>

namespace vdb_isosimp::eval {
namespace {

using namespace OpenMesh;

// Receives what OpenMesh's readers parse and keeps only positions and face index lists, without
// building connectivity: the file's topology survives unchanged (OpenMesh's own ImporterT would
// split non-manifold faces off onto duplicated vertices).
class IndexArrayImporter : public IO::BaseImporter {
public:
    explicit IndexArrayImporter(Mesh& mesh) : mesh_(mesh) {}

    VertexHandle add_vertex(const Vec3f& p) override {
        mesh_.points.push_back({p[0], p[1], p[2]});
        return VertexHandle(int(mesh_.points.size() - 1));
    }
    VertexHandle add_vertex() override { return add_vertex(Vec3f(0, 0, 0)); }
    void set_point(VertexHandle vh, const Vec3f& p) override {
        if (vh.is_valid() && size_t(vh.idx()) < mesh_.points.size())
            mesh_.points[size_t(vh.idx())] = {p[0], p[1], p[2]};
    }

    FaceHandle add_face(const VHandles& corners) override {
        if (corners.size() < 3) {
            ++shortFaces_;
            return FaceHandle();
        }
        const FaceHandle first(int(mesh_.triangles.size()));
        for (size_t i = 1; i + 1 < corners.size(); ++i) // fan for polygons
            mesh_.triangles.push_back({index(corners[0]), index(corners[i]), index(corners[i + 1])});
        return first;
    }

    void reserve(unsigned int nV, unsigned int, unsigned int nF) override {
        mesh_.points.reserve(nV);
        mesh_.triangles.reserve(nF);
    }
    size_t n_vertices() const override { return mesh_.points.size(); }
    size_t n_faces() const override { return mesh_.triangles.size(); }
    size_t n_edges() const override { return 0; }
    bool is_triangle_mesh() const override { return true; }

    size_t shortFaces() const { return shortFaces_; }
    bool badIndex() const { return badIndex_; }

    // Everything else (normals, colours, texture coordinates, status, half-edge input) is ignored.
    HalfedgeHandle add_edge(VertexHandle, VertexHandle) override { return HalfedgeHandle(); }
    FaceHandle add_face(HalfedgeHandle) override { return FaceHandle(); }
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec2f>&) override {}
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec3f>&) override {}
    void set_face_texindex(FaceHandle, int) override {}
    void set_halfedge(VertexHandle, HalfedgeHandle) override {}
    void set_normal(VertexHandle, const Vec3f&) override {}
    void set_normal(VertexHandle, const Vec3d&) override {}
    void set_color(VertexHandle, const Vec3uc&) override {}
    void set_color(VertexHandle, const Vec4uc&) override {}
    void set_color(VertexHandle, const Vec3f&) override {}
    void set_color(VertexHandle, const Vec4f&) override {}
    void set_texcoord(VertexHandle, const Vec2f&) override {}
    void set_status(VertexHandle, const Attributes::StatusInfo&) override {}
    void set_next(HalfedgeHandle, HalfedgeHandle) override {}
    void set_face(HalfedgeHandle, FaceHandle) override {}
    void request_face_texcoords2D() override {}
    void set_texcoord(HalfedgeHandle, const Vec2f&) override {}
    void set_texcoord(VertexHandle, const Vec3f&) override {}
    void set_texcoord(HalfedgeHandle, const Vec3f&) override {}
    void set_status(HalfedgeHandle, const Attributes::StatusInfo&) override {}
    void set_color(EdgeHandle, const Vec3uc&) override {}
    void set_color(EdgeHandle, const Vec4uc&) override {}
    void set_color(EdgeHandle, const Vec3f&) override {}
    void set_color(EdgeHandle, const Vec4f&) override {}
    void set_status(EdgeHandle, const Attributes::StatusInfo&) override {}
    void set_normal(FaceHandle, const Vec3f&) override {}
    void set_normal(FaceHandle, const Vec3d&) override {}
    void set_color(FaceHandle, const Vec3uc&) override {}
    void set_color(FaceHandle, const Vec4uc&) override {}
    void set_color(FaceHandle, const Vec3f&) override {}
    void set_color(FaceHandle, const Vec4f&) override {}
    void set_status(FaceHandle, const Attributes::StatusInfo&) override {}
    void add_texture_information(int, std::string) override {}

private:
    uint32_t index(VertexHandle vh) {
        if (!vh.is_valid() || size_t(vh.idx()) >= mesh_.points.size() || size_t(vh.idx()) > UINT32_MAX)
            badIndex_ = true;
        return uint32_t(vh.idx());
    }

    Mesh& mesh_;
    size_t shortFaces_ = 0;
    bool badIndex_ = false;
};

std::string lowerExtension(const std::string& path) {
    const size_t dot = path.find_last_of('.');
    const size_t slash = path.find_last_of("/\\");
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    std::string ext = path.substr(dot + 1);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

bool supportedExtension(const std::string& ext) {
    return ext == "ply" || ext == "obj" || ext == "stl" || ext == "stla" || ext == "stlb" || ext == "off";
}

// OpenMesh reports problems on its own log streams, several lines per file; the programs print one
// line of their own instead, so these are muted while OpenMesh works.
class QuietOpenMesh {
public:
    QuietOpenMesh() : err_(omerr().is_enabled()), log_(omlog().is_enabled()), out_(omout().is_enabled()) {
        omerr().disable();
        omlog().disable();
        omout().disable();
    }
    ~QuietOpenMesh() {
        if (err_) omerr().enable();
        if (log_) omlog().enable();
        if (out_) omout().enable();
    }
    QuietOpenMesh(const QuietOpenMesh&) = delete;
    QuietOpenMesh& operator=(const QuietOpenMesh&) = delete;

private:
    bool err_, log_, out_;
};

} // namespace

Mesh readMesh(const std::string& path) {
    if (!std::ifstream(path, std::ios::binary))
        throw std::runtime_error("cannot open mesh file '" + path + "'");
    const std::string ext = lowerExtension(path);
    if (!supportedExtension(ext))
        throw std::runtime_error("unsupported mesh file extension '" + path +
                                 "' (expected .ply, .obj, .stl or .off)");

    Mesh mesh;
    IndexArrayImporter importer(mesh);
    IO::Options options; // positions and faces only
    bool ok;
    {
        QuietOpenMesh quiet;
        ok = IO::IOManager().read(path, importer, options);
    }
    if (!ok) throw std::runtime_error("cannot parse mesh file '" + path + "'");
    if (importer.badIndex())
        throw std::runtime_error("mesh file '" + path + "' has a face with a vertex index out of range");
    if (importer.shortFaces() > 0)
        throw std::runtime_error("mesh file '" + path + "' has " + std::to_string(importer.shortFaces()) +
                                 " faces with fewer than 3 corners");
    return mesh;
}

TriMesh toOpenMesh(const Mesh& mesh, size_t& refusedFaces) {
    TriMesh om;
    om.reserve(mesh.points.size(), mesh.points.size() + mesh.triangles.size(), mesh.triangles.size());
    for (const auto& p : mesh.points) om.add_vertex(TriMesh::Point(p[0], p[1], p[2]));

    refusedFaces = 0;
    QuietOpenMesh quiet; // add_face logs one line per refused face
    const size_t n = mesh.points.size();
    for (const auto& t : mesh.triangles) {
        if (t[0] >= n || t[1] >= n || t[2] >= n || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
            ++refusedFaces;
            continue;
        }
        const FaceHandle fh = om.add_face(VertexHandle(int(t[0])), VertexHandle(int(t[1])), VertexHandle(int(t[2])));
        if (!fh.is_valid()) ++refusedFaces;
    }
    return om;
}

TriMesh toOpenMesh(const Mesh& mesh) {
    size_t refused = 0;
    TriMesh om = toOpenMesh(mesh, refused);
    if (refused > 0)
        throw std::runtime_error("OpenMesh refused " + std::to_string(refused) + " of " +
                                 std::to_string(mesh.triangles.size()) +
                                 " faces (complex edges or vertices, or repeated indices)");
    return om;
}

Mesh fromOpenMesh(const TriMesh& om) {
    Mesh mesh;
    std::vector<uint32_t> remap(om.n_vertices(), UINT32_MAX);
    mesh.points.reserve(om.n_vertices());
    for (const auto vh : om.vertices()) { // skips deleted elements when status is present
        const auto& p = om.point(vh);
        remap[size_t(vh.idx())] = uint32_t(mesh.points.size());
        mesh.points.push_back({p[0], p[1], p[2]});
    }
    mesh.triangles.reserve(om.n_faces());
    for (const auto fh : om.faces()) {
        std::array<uint32_t, 3> t{};
        int i = 0;
        for (const auto vh : om.fv_range(fh)) {
            if (i < 3) t[size_t(i)] = remap[size_t(vh.idx())];
            ++i;
        }
        if (i != 3) throw std::runtime_error("fromOpenMesh: face with " + std::to_string(i) + " corners");
        mesh.triangles.push_back(t);
    }
    return mesh;
}

void writeMeshOpenMesh(const Mesh& mesh, const std::string& path) {
    const std::string ext = lowerExtension(path);
    if (!supportedExtension(ext))
        throw std::runtime_error("unsupported mesh file extension '" + path +
                                 "' (expected .ply, .obj, .stl or .off)");
    const TriMesh om = toOpenMesh(mesh);
    IO::Options options;
    if (ext == "ply" || ext == "stl" || ext == "stlb") options += IO::Options::Binary;
    bool ok;
    {
        QuietOpenMesh quiet;
        ok = IO::write_mesh(om, path, options, 9);
    }
    if (!ok) throw std::runtime_error("cannot write mesh file '" + path + "'");
}

} // namespace vdb_isosimp::eval

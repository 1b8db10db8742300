// Every output format, written from one mesh and read back by an independent reader: OpenMesh's
// readers for PLY (binary and ASCII), OBJ and STL, tinygltf for glTF binary. Same vertex and face
// counts, and every triangle's corners at exactly the positions written (floats round-trip exactly:
// binary formats copy them, text formats print 9 significant digits).
#include "mesh_io.h"
#include "vdb_isosimp/mesh_writer.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include "test_files.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>
#include <tiny_gltf.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>
#include <unistd.h>

namespace vi = vdb_isosimp;

namespace {

std::string tempDir(const std::string& name)
{
    const std::string d = ::testing::TempDir() + "/formats_" + name;
    std::system(("rm -rf '" + d + "' && mkdir -p '" + d + "'").c_str());
    return d;
}

using vdb_isosimp::testing::slurp;
// The one mesh: a simplified, rotated and translated level-set sphere through the library API.
const vi::Result& sphereResult()
{
    static const vi::Result r = [] {
        openvdb::initialize();
        auto g = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(7.3f, openvdb::Vec3f(0.4f, -1.1f, 2.2f),
                                                                           0.37f);
        g->setName("density sphere");
        g->transform().postRotate(0.3, openvdb::math::X_AXIS);
        g->transform().postTranslate(openvdb::Vec3d(10.5, -3.25, 100.0));
        vi::Options o;
        o.ratio = 0.2;
        return vi::simplifyGrid(*g, o);
    }();
    return r;
}

// Corner positions of every triangle, in order: independent of how a reader numbers its vertices.
std::vector<std::array<float, 3>> corners(const vi::Mesh& m)
{
    std::vector<std::array<float, 3>> c;
    c.reserve(3 * m.triangles.size());
    for (const auto& t : m.triangles)
        for (uint32_t v : t) c.push_back(m.points.at(v));
    return c;
}

void expectSameMesh(const vi::Mesh& written, const vi::Mesh& read, const std::string& what)
{
    ASSERT_EQ(read.points.size(), written.points.size()) << what;
    ASSERT_EQ(read.triangles.size(), written.triangles.size()) << what;
    const auto a = corners(written), b = corners(read);
    size_t bad = 0;
    for (size_t i = 0; i < a.size(); ++i)
        if (a[i] != b[i]) ++bad;
    EXPECT_EQ(bad, 0u) << what << ": corners at other positions";
}

struct Gltf {
    vi::Mesh mesh;
    std::vector<std::array<float, 3>> normals;
    std::string nodeName, meshName, units;
};

// Reads a .glb with tinygltf: the first primitive's POSITION, NORMAL and indices.
Gltf readGlb(const std::string& path)
{
    tinygltf::Model model;
    tinygltf::TinyGLTF loader;
    std::string err, warn;
    const bool ok = loader.LoadBinaryFromFile(&model, &err, &warn, path);
    EXPECT_TRUE(ok) << err;
    EXPECT_EQ(warn, "");
    Gltf g;
    if (!ok || model.meshes.empty()) return g;
    g.nodeName = model.nodes.at(0).name;
    g.meshName = model.meshes[0].name;
    if (model.asset.extras.Has("units")) g.units = model.asset.extras.Get("units").Get<std::string>();
    const tinygltf::Primitive& prim = model.meshes[0].primitives.at(0);
    EXPECT_EQ(prim.mode, TINYGLTF_MODE_TRIANGLES);
    auto data = [&](int accessorIndex, int componentType, int type, size_t elementBytes) {
        const tinygltf::Accessor& acc = model.accessors.at(size_t(accessorIndex));
        EXPECT_EQ(acc.componentType, componentType);
        EXPECT_EQ(acc.type, type);
        const tinygltf::BufferView& view = model.bufferViews.at(size_t(acc.bufferView));
        const tinygltf::Buffer& buf = model.buffers.at(size_t(view.buffer));
        const size_t stride = acc.ByteStride(view);
        EXPECT_EQ(stride, elementBytes);
        EXPECT_LE(view.byteOffset + acc.byteOffset + acc.count * elementBytes, buf.data.size());
        return std::make_pair(buf.data.data() + view.byteOffset + acc.byteOffset, acc.count);
    };
    const auto pos = data(prim.attributes.at("POSITION"), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, 12);
    g.mesh.points.resize(pos.second);
    std::memcpy(g.mesh.points.data(), pos.first, 12 * pos.second);
    if (prim.attributes.count("NORMAL")) {
        const auto nrm = data(prim.attributes.at("NORMAL"), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, 12);
        g.normals.resize(nrm.second);
        std::memcpy(g.normals.data(), nrm.first, 12 * nrm.second);
    }
    const auto idx = data(prim.indices, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, 4);
    g.mesh.triangles.resize(idx.second / 3);
    std::memcpy(g.mesh.triangles.data(), idx.first, 4 * idx.second);
    return g;
}

} // namespace

TEST(Formats, TheMeshIsSuitable)
{
    // STL stores no indices: readers weld corners by position, so the counts survive only if no two
    // vertices share a position. Check that precondition rather than assume it.
    const vi::Mesh& m = sphereResult().mesh;
    ASSERT_GT(m.triangles.size(), 1000u);
    std::set<std::array<float, 3>> unique(m.points.begin(), m.points.end());
    EXPECT_EQ(unique.size(), m.points.size());
    std::vector<char> used(m.points.size(), 0);
    for (const auto& t : m.triangles)
        for (uint32_t v : t) used[v] = 1;
    EXPECT_EQ(std::count(used.begin(), used.end(), 0), 0) << "unreferenced vertices";
}

TEST(Formats, EveryFormatReadsBackTheSameMesh)
{
    const vi::Result& res = sphereResult();
    const std::string d = tempDir("roundtrip");
    for (bool normals : {false, true}) {
        vi::WriteOptions o;
        o.normals = normals;
        o.objectName = res.report.grid;
        o.comment = "vdb_isosimp grid " + res.report.grid;
        const std::string n = normals ? "_n" : "";
        vi::writeMesh(res.mesh, d + "/bin" + n + ".ply", o);
        vi::writeMesh(res.mesh, d + "/m" + n + ".obj", o);
        vi::writeMesh(res.mesh, d + "/m" + n + ".stl", o);
        vi::writeMesh(res.mesh, d + "/m" + n + ".glb", o);
        o.ascii = true;
        vi::writeMesh(res.mesh, d + "/ascii" + n + ".ply", o);

        for (const char* f : {"bin", "ascii"}) {
            const std::string path = d + "/" + f + n + ".ply";
            expectSameMesh(res.mesh, vi::eval::readMesh(path), path);
        }
        expectSameMesh(res.mesh, vi::eval::readMesh(d + "/m" + n + ".obj"), "obj" + n);
        expectSameMesh(res.mesh, vi::eval::readMesh(d + "/m" + n + ".stl"), "stl" + n);
        const Gltf g = readGlb(d + "/m" + n + ".glb");
        expectSameMesh(res.mesh, g.mesh, "glb" + n);
        EXPECT_EQ(g.nodeName, "density sphere");
        EXPECT_EQ(g.meshName, "density sphere");
        EXPECT_EQ(g.units, "world units of the grid transform");
        if (normals) {
            const auto expected = vi::vertexNormals(res.mesh);
            EXPECT_TRUE(g.normals == expected) << "glTF normals differ";
        } else {
            EXPECT_TRUE(g.normals.empty());
        }
    }
    // Grid name and units in the headers.
    EXPECT_NE(slurp(d + "/m.obj").find("\no density sphere\n"), std::string::npos);
    EXPECT_NE(slurp(d + "/m.obj").find("# units: world units of the grid transform\n"), std::string::npos);
    EXPECT_NE(slurp(d + "/bin.ply").find("\nobj_info name density sphere\n"), std::string::npos);
    EXPECT_NE(slurp(d + "/bin_n.ply").find("property float nx\n"), std::string::npos);
    EXPECT_NE(slurp(d + "/m_n.obj").find("\nvn "), std::string::npos);
    const std::string stl = slurp(d + "/m.stl");
    EXPECT_EQ(stl.rfind("vdb_isosimp grid density sphere; units", 0), 0u);
    EXPECT_EQ(stl.size(), 84 + 50 * res.mesh.triangles.size());
}

TEST(Formats, ALargeMeshReadsBackTheSameOnAnyThreadCount)
{
    // The writers format spans of consecutive items on all threads and write them in order; a mesh of
    // more faces than one round of spans holds (524,288) checks the rounds join up, against OpenMesh's
    // readers, and that one thread writes the same bytes.
    vi::Mesh m;
    const uint32_t n = 520;
    for (uint32_t j = 0; j < n; ++j)
        for (uint32_t i = 0; i < n; ++i)
            m.points.push_back({0.25f * float(i), 0.5f * float(j), std::sin(0.1f * float(i)) * std::cos(0.07f * float(j))});
    for (uint32_t j = 0; j + 1 < n; ++j)
        for (uint32_t i = 0; i + 1 < n; ++i) {
            const uint32_t a = j * n + i;
            m.triangles.push_back({a, a + 1, a + n + 1});
            m.triangles.push_back({a, a + n + 1, a + n});
        }
    ASSERT_GT(m.triangles.size(), 524288u);
    const std::string d = tempDir("large");
    for (const char* name : {"bin.ply", "ascii.ply", "m.obj", "m.stl"}) {
        vi::WriteOptions o;
        o.ascii = std::string(name) == "ascii.ply";
        const std::string path = d + "/" + name;
        vi::writeMesh(m, path, o);
        expectSameMesh(m, vi::eval::readMesh(path), name);
        tbb::task_arena one(1);
        one.execute([&] { vi::writeMesh(m, d + "/one_" + name, o); });
        EXPECT_TRUE(slurp(path) == slurp(d + "/one_" + name)) << name << ": one thread writes other bytes";
    }
}

TEST(Formats, NormalsAreAreaWeightedAndOutward)
{
    // Vertex 0 is shared by a large triangle in the z=0 plane and a small one in the x=0 plane.
    vi::Mesh m;
    m.points = {{0, 0, 0}, {10, 0, 0}, {0, 10, 0}, {0, 0, 1}, {0, 1, 0}};
    m.triangles = {{0, 1, 2}, {0, 3, 4}};
    const auto n = vi::vertexNormals(m);
    // Face normals: (0,0,100) and (-1,0,0) before normalising; weighted sum (-1, 0, 100).
    const double len = std::sqrt(1.0 + 100.0 * 100.0);
    EXPECT_NEAR(n[0][0], -1.0 / len, 1e-6);
    EXPECT_NEAR(n[0][2], 100.0 / len, 1e-6);
    EXPECT_NEAR(n[1][2], 1.0, 1e-6);
    EXPECT_NEAR(n[3][0], -1.0, 1e-6);

    // On the sphere every normal points away from the centre (counter-clockwise outward faces).
    const vi::Mesh& s = sphereResult().mesh;
    const auto sn = vi::vertexNormals(s);
    std::array<double, 3> c{0, 0, 0};
    for (const auto& p : s.points)
        for (size_t k = 0; k < 3; ++k) c[k] += p[k] / double(s.points.size());
    size_t inward = 0;
    for (size_t i = 0; i < s.points.size(); ++i) {
        double dot = 0;
        for (size_t k = 0; k < 3; ++k) dot += (s.points[i][k] - c[k]) * sn[i][k];
        if (dot <= 0) ++inward;
    }
    EXPECT_EQ(inward, 0u);
}

TEST(Formats, BadExtensionsFailWithoutLeavingFiles)
{
    const std::string d = tempDir("bad");
    const vi::Mesh& m = sphereResult().mesh;
    auto fails = [&](const std::string& name, bool ascii, const std::string& needle) {
        vi::WriteOptions o;
        o.ascii = ascii;
        try {
            vi::writeMesh(m, d + "/" + name, o);
            ADD_FAILURE() << name << " was written";
        } catch (const vi::OutputError& e) {
            EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
        }
    };
    fails("m.xyz", false, "unsupported output format");
    fails("noext", false, "unsupported output format");
    fails("m.obj", true, "only available for .ply");
    fails("m.glb", true, "only available for .ply");
    vi::Mesh nan = m;
    nan.points[7][1] = std::nanf("");
    try {
        vi::writeMesh(nan, d + "/nan.glb", vi::WriteOptions{});
        ADD_FAILURE() << "a NaN position was written";
    } catch (const vi::OutputError& e) {
        EXPECT_NE(std::string(e.what()).find("vertex 7 has a non-finite coordinate"), std::string::npos) << e.what();
    }
    EXPECT_EQ(vi::formatForPath("A.GLB"), vi::MeshFormat::Glb);
    EXPECT_EQ(vi::formatForPath("x.Ply", true), vi::MeshFormat::PlyAscii);
    FILE* p = popen(("ls -A '" + d + "'").c_str(), "r");
    char buf[256];
    std::string listing;
    while (p && fgets(buf, sizeof buf, p)) listing += buf;
    if (p) pclose(p);
    EXPECT_EQ(listing, "");
}

TEST(Formats, EmptyMeshStillMakesValidFiles)
{
    const std::string d = tempDir("empty");
    const vi::Mesh m;
    for (const char* f : {"e.ply", "e.obj", "e.stl", "e.glb"}) vi::writeMesh(m, d + "/" + f, vi::WriteOptions{});
    tinygltf::Model model;
    tinygltf::TinyGLTF loader;
    std::string err, warn;
    EXPECT_TRUE(loader.LoadBinaryFromFile(&model, &err, &warn, d + "/e.glb")) << err;
    EXPECT_EQ(vi::eval::readMesh(d + "/e.ply").triangles.size(), 0u);
}

// The library's streaming variant hands out exactly the mesh the one-call function returns.
TEST(Formats, StreamingSinkGetsTheSameMesh)
{
    openvdb::initialize();
    auto g = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(7.3f, openvdb::Vec3f(0.4f, -1.1f, 2.2f), 0.37f);
    g->setName("density sphere");
    g->transform().postRotate(0.3, openvdb::math::X_AXIS);
    g->transform().postTranslate(openvdb::Vec3d(10.5, -3.25, 100.0));
    struct Collect : vi::MeshSink {
        vi::Mesh m;
        uint64_t expectV = 0, expectF = 0;
        int begins = 0, ends = 0;
        void begin(const vi::Report& r) override { ++begins; expectV = r.vertsOut; expectF = r.facesOut; }
        void vertices(const std::array<float, 3>* p, size_t n) override { m.points.insert(m.points.end(), p, p + n); }
        void triangles(const std::array<uint32_t, 3>* t, size_t n) override
        {
            EXPECT_EQ(m.points.size(), expectV) << "triangles before all vertices";
            m.triangles.insert(m.triangles.end(), t, t + n);
        }
        void end() override { ++ends; }
    } sink;
    vi::Options o;
    o.ratio = 0.2;
    const vi::Report r = vi::simplifyGrid(*g, o, sink);
    EXPECT_EQ(sink.begins, 1);
    EXPECT_EQ(sink.ends, 1);
    EXPECT_EQ(r.file, "");
    EXPECT_EQ(r.grid, "density sphere");
    EXPECT_EQ(sink.m.triangles.size(), r.facesOut);
    EXPECT_TRUE(sink.m.points == sphereResult().mesh.points);
    EXPECT_TRUE(sink.m.triangles == sphereResult().mesh.triangles);
}

TEST(Formats, GridErrorsNameTheGrid)
{
    openvdb::initialize();
    auto g = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(5.0f, openvdb::Vec3f(0), 0.5f);
    g->setName("ball");
    vi::Options o;
    o.iso = 100.0;
    try {
        vi::simplifyGrid(*g, o);
        ADD_FAILURE() << "no error";
    } catch (const vi::EmptySurfaceError& e) {
        const std::string w = e.what();
        EXPECT_EQ(w.rfind("in-memory grid 'ball': no surface at iso-value 100", 0), 0u) << w;
        EXPECT_EQ(w.find("/tmp"), std::string::npos) << w;
    }
    auto v = openvdb::Vec3SGrid::create();
    v->setName("vel");
    EXPECT_THROW(vi::simplifyGrid(*v, vi::Options{}), vi::InputError);
    // Progress returning false cancels.
    struct Stop : vi::Progress {
        bool update(double, uint64_t) override { return false; }
    } stop;
    auto big = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(60.0f, openvdb::Vec3f(0), 0.5f);
    EXPECT_THROW(vi::simplifyGrid(*big, vi::Options{}, &stop), vi::Cancelled);
    // The caller's grid is untouched (the pipeline frees voxel buffers only of its own copy).
    EXPECT_EQ(big->tree().leafCount(), openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
                                           60.0f, openvdb::Vec3f(0), 0.5f)->tree().leafCount());
    size_t freed = 0;
    for (auto leaf = big->tree().cbeginLeaf(); leaf; ++leaf) freed += leaf->buffer().empty() ? 1 : 0;
    EXPECT_EQ(freed, 0u);
}

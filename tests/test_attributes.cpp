// Sampled vertex attributes (--attributes) end to end: every value the program writes (PLY vertex
// properties, glTF _NAME attributes) equals a trilinear interpolation of the grid at the written
// vertex, computed here from the grid's own voxels (within 1e-5 relative), for float, double and vec3
// grids with rotated and offset transforms, on a level set and on a fog; a missing or non-numeric grid
// is one line, exit 1 and no output file; OBJ and STL with attributes are usage errors. With
// --attribute-weight, an attribute with sharp fronts is carried with at least 20% less RMS error at the
// same face count.
#include "mesh_error.h"
#include "tool_runs.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>
#include <openvdb/math/Maps.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <openvdb/tools/LevelSetUtil.h>

#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <sstream>

namespace {

using namespace vdb_isosimp::testing;
using openvdb::Vec3d;

// The attribute fields, smooth in world space.
double scalarField(const Vec3d& p) { return 3.0 + std::sin(0.3 * p.x()) * std::cos(0.2 * p.y()) + 0.05 * p.z() * p.z(); }
Vec3d vectorField(const Vec3d& p) { return {p.y() - 2.0, 0.5 * p.x() * p.z(), std::cos(0.25 * p.x() + 0.1 * p.y())}; }

// A grid of `T` on `xform`, dense over the world box [-14, 14]^3 (plus a voxel), value f(world).
template <typename GridT, typename F>
typename GridT::Ptr denseGrid(const std::string& name, openvdb::math::Transform::Ptr xform, F f)
{
    auto grid = GridT::create();
    grid->setName(name);
    grid->setTransform(xform);
    Vec3d lo(HUGE_VAL), hi(-HUGE_VAL);
    for (int c = 0; c < 8; ++c) {
        const Vec3d corner(c & 1 ? 14 : -14, c & 2 ? 14 : -14, c & 4 ? 14 : -14);
        const Vec3d i = xform->worldToIndex(corner);
        lo = openvdb::math::minComponent(lo, i);
        hi = openvdb::math::maxComponent(hi, i);
    }
    auto acc = grid->getAccessor();
    for (int x = int(std::floor(lo.x())) - 1; x <= int(std::ceil(hi.x())) + 1; ++x)
        for (int y = int(std::floor(lo.y())) - 1; y <= int(std::ceil(hi.y())) + 1; ++y)
            for (int z = int(std::floor(lo.z())) - 1; z <= int(std::ceil(hi.z())) + 1; ++z) {
                const openvdb::Coord ijk(x, y, z);
                acc.setValue(ijk, typename GridT::ValueType(f(xform->indexToWorld(ijk))));
            }
    return grid;
}

// A rotation about a skew axis times a uniform scale, plus an offset.
openvdb::math::Transform::Ptr rotated(double voxel, const Vec3d& offset)
{
    openvdb::Mat4d m = openvdb::Mat4d::identity();
    m.preScale(Vec3d(voxel));
    m.postRotate(openvdb::math::X_AXIS, 0.4);
    m.postRotate(openvdb::math::Y_AXIS, -0.7);
    m.postRotate(openvdb::math::Z_AXIS, 1.1);
    m.postTranslate(offset);
    return openvdb::math::Transform::createLinearTransform(m);
}

// The meshed grid (a level set, or its fog volume) and the attribute grids, in one file.
void writeVolume(const std::string& path, bool fog)
{
    openvdb::initialize();
    auto surface = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(9.0f, openvdb::Vec3f(1, 2, 3), 0.5f);
    if (fog) openvdb::tools::sdfToFogVolume(*surface);
    surface->setName("surface");
    openvdb::GridPtrVec grids{surface};
    grids.push_back(denseGrid<openvdb::FloatGrid>("temperature", rotated(0.7, Vec3d(0.3, -0.2, 0.1)), scalarField));
    grids.push_back(denseGrid<openvdb::DoubleGrid>("pressure", openvdb::math::Transform::createLinearTransform(0.8),
                                                   [](const Vec3d& p) { return 2.0 * scalarField(p) - p.x(); }));
    grids.push_back(denseGrid<openvdb::Vec3SGrid>("velocity", rotated(0.9, Vec3d(-0.4, 0.25, 0.6)), vectorField));
    auto mask = openvdb::BoolGrid::create(false);
    mask->setName("mask");
    mask->tree().setValue(openvdb::Coord(0, 0, 0), true);
    grids.push_back(mask);
    openvdb::io::File(path).write(grids);
}

// Trilinear interpolation of component k of `grid` at world point p, from its voxels.
template <typename GridT>
double trilinear(const GridT& grid, const Vec3d& p, int k)
{
    const Vec3d i = grid.transform().worldToIndex(p);
    const openvdb::Coord base(int(std::floor(i.x())), int(std::floor(i.y())), int(std::floor(i.z())));
    const Vec3d t = i - base.asVec3d();
    auto acc = grid.getConstAccessor();
    double sum = 0.0;
    for (int c = 0; c < 8; ++c) {
        const openvdb::Coord corner = base.offsetBy(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        const double w = (c & 1 ? t.x() : 1 - t.x()) * (c & 2 ? t.y() : 1 - t.y()) * (c & 4 ? t.z() : 1 - t.z());
        const auto v = acc.getValue(corner);
        if constexpr (openvdb::VecTraits<typename GridT::ValueType>::IsVec) sum += w * double(v[k]);
        else sum += w * double(v);
    }
    return sum;
}

// Columns of an ASCII PLY's vertices, by property name.
std::map<std::string, std::vector<double>> readAsciiPly(const std::string& path)
{
    std::istringstream in(slurp(path));
    std::string line, word;
    std::vector<std::string> names;
    size_t vertices = 0;
    bool inVertex = false;
    while (std::getline(in, line) && line != "end_header") {
        std::istringstream l(line);
        l >> word;
        if (word == "element") {
            std::string what;
            l >> what;
            inVertex = what == "vertex";
            if (inVertex) l >> vertices;
        } else if (word == "property" && inVertex) {
            std::string type, name;
            l >> type >> name;
            names.push_back(name);
        }
    }
    std::map<std::string, std::vector<double>> columns;
    for (size_t v = 0; v < vertices; ++v)
        for (const std::string& n : names) {
            double x;
            in >> x;
            columns[n].push_back(x);
        }
    // The triangles, flattened, under "__faces".
    for (int count; in >> count;)
        for (int k = 0; k < count; ++k) {
            double i;
            in >> i;
            columns["__faces"].push_back(i);
        }
    return columns;
}

class Attributes : public ::testing::TestWithParam<bool> {};

TEST_P(Attributes, WrittenValuesAreTrilinearSamplesOfTheGrids)
{
    const bool fog = GetParam();
    const ScratchDir scratch;
    const std::string dir = scratch.path;
    writeVolume(dir + "/in.vdb", fog);
    const std::string run = q(VDB_ISOSIMP_EXE) + " in.vdb -q --grid surface " + (fog ? "--iso 0.5 " : "") +
                            "-r 0.3 --attributes temperature,pressure,velocity ";
    ToolRun r = runTool(dir, run + "--ascii -o out.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto ply = readAsciiPly(dir + "/out.ply");
    for (const char* name : {"x", "y", "z", "temperature", "pressure", "velocity_x", "velocity_y", "velocity_z"})
        ASSERT_EQ(ply.count(name), 1u) << name;
    const size_t n = ply.at("x").size();
    ASSERT_GT(n, 100u);

    openvdb::io::File file(dir + "/in.vdb");
    file.open();
    const auto temperature = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("temperature"));
    const auto pressure = openvdb::gridPtrCast<openvdb::DoubleGrid>(file.readGrid("pressure"));
    const auto velocity = openvdb::gridPtrCast<openvdb::Vec3SGrid>(file.readGrid("velocity"));
    file.close();
    double worst = 0.0;
    auto check = [&](const std::string& column, size_t v, double expected) {
        const double got = ply.at(column)[v];
        const double rel = std::abs(got - expected) / std::max(std::abs(expected), 1.0);
        worst = std::max(worst, rel);
        EXPECT_LE(rel, 1e-5) << column << " at vertex " << v << ": " << got << " against " << expected;
    };
    for (size_t v = 0; v < n; ++v) {
        const Vec3d p(ply.at("x")[v], ply.at("y")[v], ply.at("z")[v]);
        check("temperature", v, trilinear(*temperature, p, 0));
        check("pressure", v, trilinear(*pressure, p, 0));
        for (int k = 0; k < 3; ++k) check(std::string("velocity_") + "xyz"[k], v, trilinear(*velocity, p, k));
        // The field itself is smooth: the samples are near it (the grid's own interpolation error).
        EXPECT_NEAR(ply.at("temperature")[v], scalarField(p), 0.05);
    }
    std::printf("%s: %zu vertices, largest relative difference from the reference sample %.3g\n",
                fog ? "fog" : "level set", n, worst);

    // glTF carries the same values as custom attributes.
    r = runTool(dir, run + "-o out.glb");
    ASSERT_EQ(r.code, 0) << r.err;
    tinygltf::Model model;
    tinygltf::TinyGLTF loader;
    std::string err, warn;
    ASSERT_TRUE(loader.LoadBinaryFromFile(&model, &err, &warn, dir + "/out.glb")) << err;
    const tinygltf::Primitive& prim = model.meshes.at(0).primitives.at(0);
    for (const auto& [name, components] : std::vector<std::pair<std::string, int>>{{"temperature", 1}, {"pressure", 1}, {"velocity", 3}}) {
        ASSERT_EQ(prim.attributes.count("_" + name), 1u) << name;
        const tinygltf::Accessor& acc = model.accessors.at(size_t(prim.attributes.at("_" + name)));
        ASSERT_EQ(acc.count, n);
        EXPECT_EQ(acc.type, components == 3 ? TINYGLTF_TYPE_VEC3 : TINYGLTF_TYPE_SCALAR);
        const tinygltf::BufferView& view = model.bufferViews.at(size_t(acc.bufferView));
        const unsigned char* data = model.buffers.at(0).data.data() + view.byteOffset + acc.byteOffset;
        for (size_t v = 0; v < n; ++v)
            for (int k = 0; k < components; ++k) {
                float value;
                std::memcpy(&value, data + 4 * (v * size_t(components) + size_t(k)), 4);
                const std::string column = components == 1 ? name : name + "_" + "xyz"[k];
                EXPECT_NEAR(value, ply.at(column)[v], 1e-5 * std::max(1.0, std::abs(ply.at(column)[v]))) << column;
            }
    }
}

INSTANTIATE_TEST_SUITE_P(LevelSetAndFog, Attributes, ::testing::Values(false, true));

TEST(AttributeErrors, MissingOrNonNumericGridIsOneLineAndNoOutput)
{
    const ScratchDir scratch;
    const std::string dir = scratch.path;
    writeVolume(dir + "/in.vdb", false);
    const struct {
        const char* attributes;
        int code;
        const char* needle;
    } cases[] = {{"temperature,nosuch", 1, "no grid named 'nosuch'"},
                 {"mask", 1, "grid 'mask' has value type bool"}};
    for (const auto& c : cases) {
        const ToolRun r = runTool(dir, q(VDB_ISOSIMP_EXE) + " in.vdb --grid surface --attributes " + c.attributes + " -o out.ply");
        EXPECT_EQ(r.code, c.code) << r.err;
        EXPECT_NE(r.err.find(c.needle), std::string::npos) << r.err;
        EXPECT_NE(r.err.find("in.vdb"), std::string::npos) << "names the file: " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_EQ(unexpectedFiles(dir, {"in.vdb"}), "");
    }
    for (const char* out : {"out.obj", "out.stl"}) {
        const ToolRun r = runTool(dir, q(VDB_ISOSIMP_EXE) + " in.vdb --grid surface --attributes temperature -o " + out);
        EXPECT_EQ(r.code, 2) << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_EQ(unexpectedFiles(dir, {"in.vdb"}), "");
    }
}

// A sphere whose attribute has sharp fronts: tanh of a product of sines, crossing from -1 to 1
// within about half a voxel, on a checkerboard of cells about 12 voxels wide.
void writeFrontVolume(const std::string& path)
{
    openvdb::initialize();
    auto surface = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(30.0f, openvdb::Vec3f(0, 0, 0), 1.0f);
    surface->setName("surface");
    const auto fronts = [](const Vec3d& p) {
        return std::tanh(8.0 * std::sin(0.26 * p.x() + 0.3) * std::sin(0.26 * p.y() + 0.7) * std::sin(0.26 * p.z() + 0.1));
    };
    auto material = openvdb::FloatGrid::create();
    material->setName("material");
    auto acc = material->getAccessor();
    for (int x = -33; x <= 33; ++x)
        for (int y = -33; y <= 33; ++y)
            for (int z = -33; z <= 33; ++z) {
                const double r = std::sqrt(double(x * x + y * y + z * z));
                if (r > 26 && r < 34) acc.setValue(openvdb::Coord(x, y, z), float(fronts(Vec3d(x, y, z))));
            }
    openvdb::io::File(path).write({surface, material});
}

// RMS over the vertices of `full` of the difference between their attribute and the attribute of
// `simple` interpolated (barycentric) at the nearest point of `simple`.
double attributeRms(const std::map<std::string, std::vector<double>>& full, const std::map<std::string, std::vector<double>>& simple,
                    const std::string& name)
{
    vdb_isosimp::Mesh mesh;
    const size_t n = simple.at("x").size();
    for (size_t i = 0; i < n; ++i) mesh.points.push_back({float(simple.at("x")[i]), float(simple.at("y")[i]), float(simple.at("z")[i])});
    const auto& f = simple.at("__faces");
    for (size_t i = 0; i + 2 < f.size(); i += 3) mesh.triangles.push_back({uint32_t(f[i]), uint32_t(f[i + 1]), uint32_t(f[i + 2])});
    const vdb_isosimp::eval::TriangleBVH bvh(mesh);
    double sum = 0.0;
    const size_t m = full.at("x").size();
    for (size_t i = 0; i < m; ++i) {
        const vdb_isosimp::eval::TriangleBVH::Hit hit = bvh.nearest({full.at("x")[i], full.at("y")[i], full.at("z")[i]});
        const auto& t = mesh.triangles[hit.triangle];
        Vec3d c[3];
        for (int k = 0; k < 3; ++k) c[k] = Vec3d(mesh.points[t[k]][0], mesh.points[t[k]][1], mesh.points[t[k]][2]);
        const Vec3d p(hit.point[0], hit.point[1], hit.point[2]);
        // Barycentric coordinates of p in the triangle.
        const Vec3d e1 = c[1] - c[0], e2 = c[2] - c[0], ep = p - c[0];
        const double d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2), dp1 = ep.dot(e1), dp2 = ep.dot(e2);
        const double det = d11 * d22 - d12 * d12;
        const double v = det > 0 ? (d22 * dp1 - d12 * dp2) / det : 0.0, w = det > 0 ? (d11 * dp2 - d12 * dp1) / det : 0.0;
        const auto& a = simple.at(name);
        const double value = (1 - v - w) * a[t[0]] + v * a[t[1]] + w * a[t[2]];
        sum += (value - full.at(name)[i]) * (value - full.at(name)[i]);
    }
    return std::sqrt(sum / double(m));
}

TEST(AttributeWeight, SharpFrontsKeepLessErrorAtTheSameFaceCount)
{
    const ScratchDir scratch;
    const std::string dir = scratch.path;
    writeFrontVolume(dir + "/fronts.vdb");
    const std::string run = q(VDB_ISOSIMP_EXE) + " fronts.vdb -q --grid surface --attributes material --ascii ";
    ASSERT_EQ(runTool(dir, run + "-r 1 -o full.ply").code, 0);
    ToolRun r = runTool(dir, run + "-r 0.05 -o plain.ply --report plain.json");
    ASSERT_EQ(r.code, 0) << r.err;
    const double faces = jsonNumber(slurp(dir + "/plain.json"), "faces_out");
    r = runTool(dir, run + "--faces " + std::to_string(uint64_t(faces)) + " --attribute-weight 2 -o weighted.ply --report weighted.json");
    ASSERT_EQ(r.code, 0) << r.err;
    const double weightedFaces = jsonNumber(slurp(dir + "/weighted.json"), "faces_out");
    const auto full = readAsciiPly(dir + "/full.ply");
    const double plain = attributeRms(full, readAsciiPly(dir + "/plain.ply"), "material");
    const double weighted = attributeRms(full, readAsciiPly(dir + "/weighted.ply"), "material");
    std::printf("attribute RMS error at %.0f / %.0f faces: plain %.5f, --attribute-weight 2 %.5f (%.1f%% lower)\n", faces,
                weightedFaces, plain, weighted, 100 * (1 - weighted / plain));
    EXPECT_NEAR(weightedFaces, faces, 0.01 * faces);
    EXPECT_LE(weighted, 0.8 * plain);
    // Weighting is a usage error without an attribute, or with a weight that is not positive.
    for (const char* bad : {"--attribute-weight 2", "--attributes material --attribute-weight 0",
                            "--attributes material --attribute-weight -1"}) {
        const ToolRun u = runTool(dir, q(VDB_ISOSIMP_EXE) + " fronts.vdb --grid surface " + bad + " -o bad.ply");
        EXPECT_EQ(u.code, 2) << bad << ": " << u.err;
        EXPECT_FALSE(exists(dir + "/bad.ply"));
    }
}

} // namespace

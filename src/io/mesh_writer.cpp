#include "vdb_isosimp/mesh_writer.h"
#include "vdb_isosimp/temporary_file.h"

#include <tbb/parallel_for.h>
#include <tiny_gltf.h>

#include "vdb_isosimp/errors.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <sstream>
#include <string>
#include <sys/stat.h>
#include <unistd.h>
#include <vector>

namespace vdb_isosimp {

namespace {

constexpr const char* kUnits = "units: world units of the grid transform";

bool hostIsLittleEndian()
{
    const uint16_t one = 1;
    unsigned char b;
    std::memcpy(&b, &one, 1);
    return b == 1;
}

std::string extensionOf(const std::string& path)
{
    const auto slash = path.find_last_of('/');
    const auto dot = path.find_last_of('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return {};
    std::string e = path.substr(dot + 1);
    for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
    return e;
}

// Header text must stay on one line (PLY comments, OBJ comments and names are line-based).
std::string oneLine(std::string s)
{
    for (char& c : s)
        if (c == '\n' || c == '\r' || c == '\0') c = ' ';
    return s;
}

// %.9g: shortest form that still reads back as the same float.
void appendFloat(std::string& s, float v)
{
    char b[32];
    const int n = std::snprintf(b, sizeof b, "%.9g", double(v));
    s.append(b, size_t(n));
}

// Buffered writes into the temporary file; stream errors surface at the end (ferror/fflush/fclose).
class Out {
public:
    explicit Out(std::FILE* f) : mF(f) { mBuf.reserve(kChunk + 256); }
    ~Out() { flush(); }
    void bytes(const void* p, size_t n)
    {
        const auto* c = static_cast<const unsigned char*>(p);
        if (n >= kDirect) {  // a copy into the buffer would cost more than the extra write call
            flush();
            std::fwrite(c, 1, n, mF);
            return;
        }
        mBuf.insert(mBuf.end(), c, c + n);
        if (mBuf.size() >= kChunk) flush();
    }
    void text(const std::string& s) { bytes(s.data(), s.size()); }
    // Items [0, count), each appended to a byte string by append(i, s): made on all threads in spans
    // of consecutive items, written in order, so the bytes are a serial loop's. The whole mesh is
    // never formatted at once: at most kSpansAtOnce spans are held.
    template <typename Append> void items(size_t count, const Append& append)
    {
        constexpr size_t kSpan = 16384, kSpansAtOnce = 32;
        std::vector<std::string> spans;
        for (size_t first = 0; first < count; first += kSpan * kSpansAtOnce) {
            spans.resize(std::min(kSpansAtOnce, (count - first + kSpan - 1) / kSpan));
            tbb::parallel_for(size_t(0), spans.size(), [&](size_t k) {
                std::string& out = spans[k];
                out.clear();
                const size_t begin = first + k * kSpan, end = std::min(count, begin + kSpan);
                for (size_t i = begin; i < end; ++i) append(i, out);
            });
            for (const std::string& span : spans) text(span);
        }
    }
    template <typename T> void pod(const T& v) { bytes(&v, sizeof v); }
    void zeros(size_t n)
    {
        static const unsigned char z[4] = {0, 0, 0, 0};
        bytes(z, n);
    }
    void flush()
    {
        if (!mBuf.empty()) std::fwrite(mBuf.data(), 1, mBuf.size(), mF);
        mBuf.clear();
    }

private:
    static constexpr size_t kChunk = 1 << 20, kDirect = 1 << 16;
    std::FILE* mF;
    std::vector<unsigned char> mBuf;
};

std::array<double, 3> faceNormal(const Mesh& m, const std::array<uint32_t, 3>& t)
{
    const auto& a = m.points[t[0]];
    const auto& b = m.points[t[1]];
    const auto& c = m.points[t[2]];
    const double u[3] = {double(b[0]) - a[0], double(b[1]) - a[1], double(b[2]) - a[2]};
    const double v[3] = {double(c[0]) - a[0], double(c[1]) - a[1], double(c[2]) - a[2]};
    return {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
}

void checkIndices(const Mesh& mesh)
{
    const size_t n = mesh.points.size();
    for (const auto& t : mesh.triangles)
        if (t[0] >= n || t[1] >= n || t[2] >= n) throw OutputError("mesh has a vertex index out of range");
}

// No format can say what a NaN or infinite position means (and glTF's JSON cannot even hold one).
void checkFinite(const Mesh& mesh)
{
    for (size_t i = 0; i < mesh.points.size(); ++i)
        for (float c : mesh.points[i])
            if (!std::isfinite(c))
                throw OutputError("vertex " + std::to_string(i) + " has a non-finite coordinate");
}

// Each attribute has 1 or 3 values per point and a name a PLY header can hold.
void checkAttributes(const Mesh& mesh)
{
    for (const VertexAttribute& a : mesh.attributes) {
        if (a.components != 1 && a.components != 3)
            throw OutputError("attribute '" + a.name + "' has " + std::to_string(a.components) + " components (1 or 3)");
        if (a.values.size() != size_t(a.components) * mesh.points.size())
            throw OutputError("attribute '" + a.name + "' has " + std::to_string(a.values.size()) + " values for " +
                              std::to_string(mesh.points.size()) + " vertices");
        if (a.name.empty() || a.name.find_first_of(" \t\r\n") != std::string::npos)
            throw OutputError("attribute name '" + a.name + "' is empty or holds white space");
    }
}

// The PLY property names of an attribute: the grid's name, or NAME_x NAME_y NAME_z for a vector.
std::vector<std::string> plyPropertyNames(const VertexAttribute& a)
{
    if (a.components == 1) return {a.name};
    return {a.name + "_x", a.name + "_y", a.name + "_z"};
}

void writePly(const Mesh& mesh, Out& out, const WriteOptions& o, bool ascii)
{
    std::vector<std::array<float, 3>> normals;
    if (o.normals) normals = vertexNormals(mesh);
    std::string h = "ply\nformat ";
    h += ascii ? "ascii 1.0\n" : "binary_little_endian 1.0\n";
    if (!o.comment.empty()) h += "comment " + oneLine(o.comment) + "\n";
    h += std::string("comment ") + kUnits + "\n";
    if (!o.objectName.empty()) h += "obj_info name " + oneLine(o.objectName) + "\n";
    h += "element vertex " + std::to_string(mesh.points.size()) +
         "\nproperty float x\nproperty float y\nproperty float z\n";
    if (o.normals) h += "property float nx\nproperty float ny\nproperty float nz\n";
    for (const VertexAttribute& a : mesh.attributes)
        for (const std::string& name : plyPropertyNames(a)) h += "property float " + name + "\n";
    h += "element face " + std::to_string(mesh.triangles.size()) +
         "\nproperty list uchar int vertex_indices\nend_header\n";
    out.text(h);

    if (ascii) {
        out.items(mesh.points.size(), [&](size_t i, std::string& line) {
            const auto& p = mesh.points[i];
            for (int k = 0; k < 3; ++k) {
                if (k) line += ' ';
                appendFloat(line, p[size_t(k)]);
            }
            if (o.normals)
                for (int k = 0; k < 3; ++k) {
                    line += ' ';
                    appendFloat(line, normals[i][size_t(k)]);
                }
            for (const VertexAttribute& a : mesh.attributes)
                for (uint32_t k = 0; k < a.components; ++k) {
                    line += ' ';
                    appendFloat(line, a.values[i * a.components + k]);
                }
            line += '\n';
        });
        out.items(mesh.triangles.size(), [&](size_t i, std::string& line) {
            const auto& t = mesh.triangles[i];
            line += "3 " + std::to_string(t[0]) + ' ' + std::to_string(t[1]) + ' ' + std::to_string(t[2]) + '\n';
        });
        return;
    }

    if (!hostIsLittleEndian()) throw OutputError("big-endian hosts are not supported by the binary writers");
    if (o.normals || !mesh.attributes.empty()) {
        out.items(mesh.points.size(), [&](size_t i, std::string& rec) {
            rec.append(reinterpret_cast<const char*>(mesh.points[i].data()), 12);
            if (o.normals) rec.append(reinterpret_cast<const char*>(normals[i].data()), 12);
            for (const VertexAttribute& a : mesh.attributes)
                rec.append(reinterpret_cast<const char*>(&a.values[i * a.components]), sizeof(float) * a.components);
        });
    } else {
        out.bytes(mesh.points.data(), sizeof(float) * 3 * mesh.points.size());
    }
    out.items(mesh.triangles.size(), [&](size_t i, std::string& s) {
        const auto& t = mesh.triangles[i];
        char rec[13];
        rec[0] = 3;
        const int32_t idx[3] = {int32_t(t[0]), int32_t(t[1]), int32_t(t[2])};
        std::memcpy(rec + 1, idx, 12);
        s.append(rec, 13);
    });
}

void writeObj(const Mesh& mesh, Out& out, const WriteOptions& o)
{
    std::vector<std::array<float, 3>> normals;
    if (o.normals) normals = vertexNormals(mesh);
    std::string h = "# vdb_isosimp\n";
    if (!o.comment.empty()) h += "# " + oneLine(o.comment) + "\n";
    h += std::string("# ") + kUnits + "\n";
    h += "# " + std::to_string(mesh.points.size()) + " vertices, " + std::to_string(mesh.triangles.size()) +
         " triangles\n";
    h += "o " + oneLine(o.objectName.empty() ? std::string("vdb_isosimp") : o.objectName) + "\n";
    out.text(h);
    const auto vectors = [&](const char* tag, const std::vector<std::array<float, 3>>& v) {
        out.items(v.size(), [&](size_t i, std::string& line) {
            line += tag;
            for (int k = 0; k < 3; ++k) {
                line += ' ';
                appendFloat(line, v[i][size_t(k)]);
            }
            line += '\n';
        });
    };
    vectors("v", mesh.points);
    vectors("vn", normals);
    out.items(mesh.triangles.size(), [&](size_t f, std::string& line) {
        const auto& t = mesh.triangles[f];
        line += 'f';
        for (int k = 0; k < 3; ++k) {
            const std::string i = std::to_string(uint64_t(t[size_t(k)]) + 1);  // OBJ counts from 1
            line += ' ';
            line += i;
            if (o.normals) line += "//" + i;
        }
        line += '\n';
    });
}

void writeStl(const Mesh& mesh, Out& out, const WriteOptions& o)
{
    if (!hostIsLittleEndian()) throw OutputError("big-endian hosts are not supported by the binary writers");
    if (mesh.triangles.size() > std::numeric_limits<uint32_t>::max())
        throw OutputError("too many triangles for STL (at most 2^32 - 1)");
    // 80 bytes of free text; must not start with "solid", or readers take the file for ASCII STL.
    std::string h = "vdb_isosimp";
    if (!o.objectName.empty()) h += " grid " + oneLine(o.objectName);
    h += std::string("; ") + kUnits;
    h.resize(80, ' ');
    out.text(h);
    out.pod(uint32_t(mesh.triangles.size()));
    out.items(mesh.triangles.size(), [&](size_t i, std::string& s) {
        const auto& t = mesh.triangles[i];
        const auto n = faceNormal(mesh, t);
        const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        float rec[12];
        for (int k = 0; k < 3; ++k) rec[k] = len > 0 ? float(n[size_t(k)] / len) : 0.0f;
        for (int c = 0; c < 3; ++c)
            for (int k = 0; k < 3; ++k) rec[3 + 3 * c + k] = mesh.points[t[size_t(c)]][size_t(k)];
        s.append(reinterpret_cast<const char*>(rec), sizeof rec);
        s.append(2, '\0');  // attribute byte count
    });
}

// glTF 2.0 binary through tinygltf (Debian's libtinygltf-dev): one node, one triangle primitive with
// POSITION (+ NORMAL) and 32-bit indices in one buffer. The units and comment go into asset.extras.
void writeGlb(const Mesh& mesh, Out& out, const WriteOptions& o)
{
    if (!hostIsLittleEndian()) throw OutputError("big-endian hosts are not supported by the binary writers");
    const uint64_t nv = mesh.points.size(), nt = mesh.triangles.size();
    uint64_t attrBytes = 0;
    for (const VertexAttribute& a : mesh.attributes) attrBytes += 4 * uint64_t(a.components) * nv;
    const uint64_t posBytes = 12 * nv, nrmBytes = o.normals ? 12 * nv : 0, idxBytes = 12 * nt;
    if (posBytes + nrmBytes + attrBytes + idxBytes + (1u << 20) > std::numeric_limits<uint32_t>::max())
        throw OutputError("mesh too large for a .glb file (4 GiB at most); write .ply instead");
    const std::string name = o.objectName.empty() ? std::string("vdb_isosimp") : o.objectName;

    tinygltf::Model model;
    model.asset.version = "2.0";
    model.asset.generator = "vdb_isosimp";
    tinygltf::Value::Object extras;
    extras["units"] = tinygltf::Value(std::string(kUnits).substr(7));
    if (!o.comment.empty()) extras["comment"] = tinygltf::Value(o.comment);
    model.asset.extras = tinygltf::Value(extras);
    tinygltf::Scene scene;
    scene.name = name;
    scene.nodes = {0};
    model.scenes.push_back(scene);
    model.defaultScene = 0;
    tinygltf::Node node;
    node.name = name;
    if (nv > 0 && nt > 0) {  // glTF accessors must not be empty
        node.mesh = 0;
        tinygltf::Buffer buffer;
        buffer.data.resize(posBytes + nrmBytes + attrBytes + idxBytes);
        std::memcpy(buffer.data.data(), mesh.points.data(), posBytes);
        if (o.normals) {
            const auto normals = vertexNormals(mesh);
            std::memcpy(buffer.data.data() + posBytes, normals.data(), nrmBytes);
        }
        // Attributes follow the normals, one tightly packed view each.
        size_t attrOffset = posBytes + nrmBytes;
        for (const VertexAttribute& a : mesh.attributes) {
            std::memcpy(buffer.data.data() + attrOffset, a.values.data(), 4 * a.values.size());
            attrOffset += 4 * a.values.size();
        }
        std::memcpy(buffer.data.data() + posBytes + nrmBytes + attrBytes, mesh.triangles.data(), idxBytes);
        model.buffers.push_back(std::move(buffer));

        auto addView = [&](size_t offset, size_t length, int target) {
            tinygltf::BufferView v;
            v.buffer = 0;
            v.byteOffset = offset;
            v.byteLength = length;
            v.target = target;
            model.bufferViews.push_back(v);
            return int(model.bufferViews.size() - 1);
        };
        auto addAccessor = [&](int view, int componentType, size_t count, int type) {
            tinygltf::Accessor a;
            a.bufferView = view;
            a.componentType = componentType;
            a.count = count;
            a.type = type;
            model.accessors.push_back(a);
            return int(model.accessors.size() - 1);
        };
        tinygltf::Primitive prim;
        prim.mode = TINYGLTF_MODE_TRIANGLES;
        prim.attributes["POSITION"] = addAccessor(addView(0, posBytes, TINYGLTF_TARGET_ARRAY_BUFFER),
                                                  TINYGLTF_COMPONENT_TYPE_FLOAT, nv, TINYGLTF_TYPE_VEC3);
        // POSITION needs its bounds.
        std::array<float, 3> lo = mesh.points[0], hi = mesh.points[0];
        for (const auto& p : mesh.points)
            for (size_t k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], p[k]);
                hi[k] = std::max(hi[k], p[k]);
            }
        model.accessors.back().minValues = {lo[0], lo[1], lo[2]};
        model.accessors.back().maxValues = {hi[0], hi[1], hi[2]};
        if (o.normals)
            prim.attributes["NORMAL"] = addAccessor(addView(posBytes, nrmBytes, TINYGLTF_TARGET_ARRAY_BUFFER),
                                                    TINYGLTF_COMPONENT_TYPE_FLOAT, nv, TINYGLTF_TYPE_VEC3);
        // Application-specific attributes: glTF requires the leading underscore.
        attrOffset = posBytes + nrmBytes;
        for (const VertexAttribute& a : mesh.attributes) {
            const size_t bytes = 4 * a.values.size();
            prim.attributes["_" + a.name] = addAccessor(addView(attrOffset, bytes, TINYGLTF_TARGET_ARRAY_BUFFER),
                                                        TINYGLTF_COMPONENT_TYPE_FLOAT, nv,
                                                        a.components == 3 ? TINYGLTF_TYPE_VEC3 : TINYGLTF_TYPE_SCALAR);
            attrOffset += bytes;
        }
        prim.indices = addAccessor(addView(posBytes + nrmBytes + attrBytes, idxBytes, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER),
                                   TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, 3 * nt, TINYGLTF_TYPE_SCALAR);
        tinygltf::Mesh m;
        m.name = name;
        m.primitives.push_back(prim);
        model.meshes.push_back(m);
    }
    model.nodes.push_back(node);

    std::ostringstream glb;
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToStream(&model, glb, /*prettyPrint=*/false, /*writeBinary=*/true))
        throw OutputError("the glTF writer failed");
    out.text(glb.str());
}

} // namespace

MeshFormat formatForPath(const std::string& path, bool ascii)
{
    const std::string ext = extensionOf(path);
    if (ascii && ext != "ply")
        throw OutputError(path + ": ASCII output is only available for .ply (OBJ is always text; STL and "
                                 "glTF are written binary)");
    if (ext == "ply") return ascii ? MeshFormat::PlyAscii : MeshFormat::PlyBinary;
    if (ext == "obj") return MeshFormat::Obj;
    if (ext == "stl") return MeshFormat::StlBinary;
    if (ext == "glb") return MeshFormat::Glb;
    throw OutputError(path + ": unsupported output format '." + ext + "' (supported: .ply, .obj, .stl, .glb)");
}

bool formatHoldsAttributes(MeshFormat format)
{
    return format == MeshFormat::PlyBinary || format == MeshFormat::PlyAscii || format == MeshFormat::Glb;
}

std::vector<std::array<float, 3>> vertexNormals(const Mesh& mesh)
{
    checkIndices(mesh);
    std::vector<std::array<double, 3>> sum(mesh.points.size(), {0.0, 0.0, 0.0});
    for (const auto& t : mesh.triangles) {
        const auto n = faceNormal(mesh, t);  // length = twice the area: area weighting for free
        for (uint32_t v : t)
            for (size_t k = 0; k < 3; ++k) sum[v][k] += n[k];
    }
    std::vector<std::array<float, 3>> out(mesh.points.size());
    for (size_t i = 0; i < sum.size(); ++i) {
        const auto& s = sum[i];
        const double len = std::sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
        out[i] = len > 0 ? std::array<float, 3>{float(s[0] / len), float(s[1] / len), float(s[2] / len)}
                         : std::array<float, 3>{0.0f, 0.0f, 1.0f};
    }
    return out;
}

void writeMesh(const Mesh& mesh, const std::string& path, const WriteOptions& options)
{
    const MeshFormat format = formatForPath(path, options.ascii);
    try {
        checkIndices(mesh);
        checkFinite(mesh);
        checkAttributes(mesh);
        if (!mesh.attributes.empty() && !formatHoldsAttributes(format))
            throw OutputError("OBJ and STL have no vertex attributes; write .ply or .glb");
    } catch (const OutputError& e) {
        throw OutputError(path + ": " + e.what());
    }
    // An existing device or FIFO (/dev/stdout, /dev/full, a named pipe, or a link to one) is written
    // in place: a temporary file renamed over it would replace the node itself. A directory is refused.
    struct stat st {};
    const bool exists = ::stat(path.c_str(), &st) == 0;
    if (exists && S_ISDIR(st.st_mode)) throw OutputError(path + ": cannot create output file (" + std::strerror(EISDIR) + ")");
    const bool inPlace = exists && !S_ISREG(st.st_mode);
    const std::string tmp = inPlace ? path : temporaryPathFor(path);
    auto discard = [&] {
        if (!inPlace) std::remove(tmp.c_str());
    };
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw OutputError(path + ": cannot create output file (" + std::strerror(errno) + ")");
    try {
        Out out(f);
        switch (format) {
        case MeshFormat::PlyBinary: writePly(mesh, out, options, false); break;
        case MeshFormat::PlyAscii: writePly(mesh, out, options, true); break;
        case MeshFormat::Obj: writeObj(mesh, out, options); break;
        case MeshFormat::StlBinary: writeStl(mesh, out, options); break;
        case MeshFormat::Glb: writeGlb(mesh, out, options); break;
        }
    } catch (const OutputError& e) {
        std::fclose(f);
        discard();
        throw OutputError(path + ": " + e.what());
    } catch (...) {
        std::fclose(f);
        discard();
        throw;
    }
    // Any earlier short write shows up in the stream's error flag or at fflush/fclose (e.g. disk full).
    const bool bad = std::ferror(f) != 0 || std::fflush(f) != 0;
    const int err = errno;
    if (std::fclose(f) != 0 || bad) {
        discard();
        throw OutputError(path + ": write failed (" + std::strerror(bad ? err : errno) + ")");
    }
    if (!inPlace && std::rename(tmp.c_str(), path.c_str()) != 0) {
        const int e = errno;
        std::remove(tmp.c_str());
        throw OutputError(path + ": cannot move the finished mesh into place (" + std::strerror(e) + ")");
    }
}

void writeMesh(const Mesh& mesh, const std::string& path, const std::string& comment)
{
    WriteOptions o;
    o.comment = comment;
    writeMesh(mesh, path, o);
}

} // namespace vdb_isosimp

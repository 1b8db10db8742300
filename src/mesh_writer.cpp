#include "mesh_writer.h"

#include "errors.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>
#include <unistd.h>
#include <vector>

namespace vdb_isosimp {

namespace {

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

void writePly(const Mesh& mesh, std::FILE* f, const std::string& comment)
{
    std::string header = "ply\nformat binary_little_endian 1.0\n";
    if (!comment.empty()) header += "comment " + comment + "\n";
    header += "element vertex " + std::to_string(mesh.points.size()) +
              "\nproperty float x\nproperty float y\nproperty float z\n"
              "element face " + std::to_string(mesh.triangles.size()) +
              "\nproperty list uchar int vertex_indices\nend_header\n";
    std::fwrite(header.data(), 1, header.size(), f);
    if (!hostIsLittleEndian()) throw OutputError("big-endian hosts are not supported by the PLY writer");
    std::fwrite(mesh.points.data(), sizeof(float) * 3, mesh.points.size(), f);
    // 13 bytes per face; write through a buffer instead of one fwrite per face.
    std::vector<unsigned char> buf;
    buf.reserve(13 * 4096);
    for (size_t i = 0; i < mesh.triangles.size(); ++i) {
        buf.push_back(3);
        const auto& t = mesh.triangles[i];
        const int32_t idx[3] = {int32_t(t[0]), int32_t(t[1]), int32_t(t[2])};
        const auto* p = reinterpret_cast<const unsigned char*>(idx);
        buf.insert(buf.end(), p, p + 12);
        if (buf.size() >= 13 * 4096) {
            std::fwrite(buf.data(), 1, buf.size(), f);
            buf.clear();
        }
    }
    std::fwrite(buf.data(), 1, buf.size(), f);
}

} // namespace

void writeMesh(const Mesh& mesh, const std::string& path, const std::string& comment)
{
    const std::string ext = extensionOf(path);
    if (ext != "ply")
        throw OutputError(path + ": unsupported output format '." + ext + "' (supported: .ply)");
    const std::string tmp = path + ".tmp" + std::to_string(::getpid());
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw OutputError(path + ": cannot create output file (" + std::strerror(errno) + ")");
    try {
        writePly(mesh, f, comment);
    } catch (...) {
        std::fclose(f);
        std::remove(tmp.c_str());
        throw;
    }
    // Any earlier short write shows up in the stream's error flag or at fflush/fclose (e.g. disk full).
    const bool bad = std::ferror(f) != 0 || std::fflush(f) != 0;
    const int err = errno;
    if (std::fclose(f) != 0 || bad) {
        std::remove(tmp.c_str());
        throw OutputError(path + ": write failed (" + std::strerror(bad ? err : errno) + ")");
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const int e = errno;
        std::remove(tmp.c_str());
        throw OutputError(path + ": cannot move the finished mesh into place (" + std::strerror(e) + ")");
    }
}

} // namespace vdb_isosimp

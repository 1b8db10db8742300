// The paper's out-of-core cascade (section 5): out-of-core extraction, then cutting-based
// out-of-core simplification (Brodsky and Pedersen 2003 style), never holding the full surface.
//   1. extract: our Marching Cubes, block by block in z/y/x order, streamed to a temporary file as a
//      triangle soup whose corners carry their global edge keys (so pieces can be welded exactly);
//   2. cut: the soup is split into k x k x k boxes of the bounding box by triangle centroid, one
//      file per box;
//   3. each piece is loaded, welded and decimated alone with OpenMesh (ModQuadricT + normal
//      flipping, as baseline_openmesh) to its share of the target (rate R on its faces that do
//      not touch the cut), with the vertices on the cut locked so neighbouring pieces still fit;
//   4. the pieces are stitched on the locked vertices and one final pass over the stitched mesh
//      (now without locks) brings it to the target.
// Prints one JSON line (baseline_openmesh's keys plus per-phase time, peak memory and disk bytes).
#include "bench_util.h"
#include "core/marching_cubes.h"
#include "eval_openmesh.h"
#include "pipeline/run_stats.h"
#include "reference_decimate.h"
#include "vdb/volume_reader.h"
#include "vdb_isosimp/mesh_writer.h"

#include <CLI/CLI.hpp>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>
#include <tbb/parallel_pipeline.h>

#include <malloc.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <thread>
#include <unordered_map>

using namespace vdb_isosimp;
namespace fs = std::filesystem;

namespace {

// One triangle of the soup: corner edge keys and positions. 60 bytes on disk.
#pragma pack(push, 4)
struct TriRecord {
    uint64_t key[3];
    float p[3][3];
};
#pragma pack(pop)
static_assert(sizeof(TriRecord) == 60, "soup records are 60 bytes");

// A private temporary directory, removed with everything in it.
struct TempDir {
    fs::path path;
    explicit TempDir(const fs::path& parent)
    {
        std::string t = (parent / "vdb_isosimp_cascade.XXXXXX").string();
        if (!mkdtemp(t.data())) throw std::runtime_error("cannot create a temporary directory in " + parent.string());
        path = t;
    }
    ~TempDir()
    {
        std::error_code ec;
        fs::remove_all(path, ec);
    }
};

// Buffered binary file of records.
class RecordFile {
public:
    RecordFile(const fs::path& p, const char* mode) : f_(std::fopen(p.c_str(), mode)), path_(p)
    {
        if (!f_) throw std::runtime_error("cannot open " + p.string());
        std::setvbuf(f_, nullptr, _IOFBF, 1 << 20);
    }
    ~RecordFile() { if (f_) std::fclose(f_); }
    void write(const TriRecord* r, size_t n)
    {
        if (n && std::fwrite(r, sizeof(TriRecord), n, f_) != n) throw std::runtime_error("write failed: " + path_.string());
        bytes_ += n * sizeof(TriRecord);
    }
    size_t read(TriRecord* r, size_t n) { return std::fread(r, sizeof(TriRecord), n, f_); }
    void close()
    {
        if (f_ && std::fclose(f_) != 0) throw std::runtime_error("write failed: " + path_.string());
        f_ = nullptr;
    }
    uint64_t bytes() const { return bytes_; }

private:
    FILE* f_;
    fs::path path_;
    uint64_t bytes_ = 0;
};

struct Extraction {
    uint64_t faces = 0;
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    uint64_t bytes = 0;
};

// Phase 1: our block-wise Marching Cubes (parallel, as the pipeline), written in block order.
Extraction extractToSoup(const std::string& input, const std::string& gridName, const double* iso,
                         const fs::path& soupPath)
{
    std::unique_ptr<Volume> vol = Volume::open(input, gridName);
    const VolumeInfo& info = vol->info();
    Classifier cls;
    cls.insideBelow = info.levelSet;
    if (iso) cls.iso = *iso;
    else if (info.levelSet) cls.iso = 0.0;
    else {
        const auto r = vol->valueRange();
        cls.iso = 0.5 * (r[0] + r[1]);
    }
    const bool flip = info.indexToWorld.determinant() < 0;
    const std::vector<std::array<int32_t, 3>> blocks = vol->blocks(cls);

    Extraction ex;
    RecordFile soup(soupPath, "wb");
    std::vector<TriRecord> buf;
    size_t next = 0;
    tbb::parallel_pipeline(
        4 * std::max<size_t>(1, std::thread::hardware_concurrency()),
        tbb::make_filter<void, size_t>(tbb::filter_mode::serial_in_order,
                                       [&](tbb::flow_control& fc) -> size_t {
                                           if (next == blocks.size()) { fc.stop(); return 0; }
                                           return next++;
                                       }) &
            tbb::make_filter<size_t, std::shared_ptr<BlockMesh>>(tbb::filter_mode::parallel,
                                                                 [&](size_t i) {
                                                                     BlockSamples s;
                                                                     vol->sample(blocks[i], s);
                                                                     auto m = std::make_shared<BlockMesh>();
                                                                     m->blockIndex = i;
                                                                     extractBlock(s, cls, info.indexToWorld, flip, *m);
                                                                     return m;
                                                                 }) &
            tbb::make_filter<std::shared_ptr<BlockMesh>, void>(
                tbb::filter_mode::serial_in_order, [&](std::shared_ptr<BlockMesh> m) {
                    buf.clear();
                    for (const auto& t : m->triangles) {
                        TriRecord r;
                        for (int c = 0; c < 3; ++c) {
                            r.key[c] = m->keys[t[c]];
                            for (int a = 0; a < 3; ++a) {
                                r.p[c][a] = float(m->positions[t[c]][a]);
                                ex.lo[a] = std::min(ex.lo[a], double(r.p[c][a]));
                                ex.hi[a] = std::max(ex.hi[a], double(r.p[c][a]));
                            }
                        }
                        buf.push_back(r);
                    }
                    soup.write(buf.data(), buf.size());
                    ex.faces += buf.size();
                    vol->releaseLeaf(blocks[m->blockIndex]);
                }));
    soup.close();
    ex.bytes = soup.bytes();
    return ex;
}

// Binary module: no collapse into a locked (cut) vertex either. DecimaterT already refuses to move
// a locked vertex; without this, collapses into cut vertices could create the same new edge between
// two cut vertices in two pieces, and the stitched mesh would be non-manifold there.
template <class MeshT>
class ModKeepCutT : public OpenMesh::Decimater::ModBaseT<MeshT> {
public:
    DECIMATING_MODULE(ModKeepCutT, MeshT, KeepCut);
    explicit ModKeepCutT(MeshT& mesh) : Base(mesh, true) {}
    float collapse_priority(const CollapseInfo& ci) override
    {
        return Base::mesh().status(ci.v1).locked() ? float(Base::ILLEGAL_COLLAPSE) : float(Base::LEGAL_COLLAPSE);
    }
};

// A piece can hold a vertex whose faces form several fans (the faces between them went to other
// pieces); OpenMesh refuses such "complex" vertices. Each extra fan gets its own copy of the vertex
// (same key: on the cut, so locked, and merged again when the pieces are stitched).
// Returns the copies' vertex indices and the vertices they were split from.
std::vector<uint32_t> splitPinchedVertices(Mesh& m, std::vector<uint64_t>& keys)
{
    std::vector<uint32_t> pinched;
    const size_t nv = m.points.size();
    std::vector<uint32_t> start(nv + 1, 0), corner(3 * m.triangles.size());
    for (const auto& t : m.triangles)
        for (uint32_t v : t) ++start[v + 1];
    for (size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (uint32_t f = 0; f < m.triangles.size(); ++f)
        for (int c = 0; c < 3; ++c) corner[fill[m.triangles[f][c]]++] = 3 * f + c;  // face * 3 + corner

    std::vector<uint32_t> parent;
    std::vector<std::pair<uint32_t, uint32_t>> neighbours;  // (other vertex, local face position)
    for (uint32_t v = 0; v < nv; ++v) {
        const uint32_t b = start[v], d = start[v + 1] - b;
        if (d < 2) continue;
        parent.resize(d);
        for (uint32_t i = 0; i < d; ++i) parent[i] = i;
        auto find = [&](uint32_t i) {
            while (parent[i] != i) i = parent[i] = parent[parent[i]];
            return i;
        };
        neighbours.clear();
        for (uint32_t i = 0; i < d; ++i) {
            const uint32_t f = corner[b + i] / 3, c = corner[b + i] % 3;
            neighbours.push_back({m.triangles[f][(c + 1) % 3], i});
            neighbours.push_back({m.triangles[f][(c + 2) % 3], i});
        }
        // Faces sharing an edge (v, w) belong to the same fan.
        std::sort(neighbours.begin(), neighbours.end());
        for (size_t j = 1; j < neighbours.size(); ++j)
            if (neighbours[j].first == neighbours[j - 1].first)
                parent[find(neighbours[j].second)] = find(neighbours[j - 1].second);
        const uint32_t first = find(0);
        std::vector<std::pair<uint32_t, uint32_t>> copies;  // (fan root, new vertex)
        for (uint32_t i = 0; i < d; ++i) {
            const uint32_t r = find(i);
            if (r == first) continue;
            auto it = std::find_if(copies.begin(), copies.end(), [&](const auto& c) { return c.first == r; });
            if (it == copies.end()) {
                if (copies.empty()) pinched.push_back(v);
                pinched.push_back(uint32_t(m.points.size()));
                copies.push_back({r, uint32_t(m.points.size())});
                m.points.push_back(m.points[v]);
                keys.push_back(keys[v]);
                it = copies.end() - 1;
            }
            const uint32_t f = corner[b + i] / 3, c = corner[b + i] % 3;
            m.triangles[f][c] = it->second;
        }
    }
    return pinched;
}

// Phase 3 for one piece: weld by edge key, lock the cut, decimate. Returns the decimated piece and,
// per vertex, its edge key and whether it is on the cut (locked, so still at its original place).
Mesh simplifyPiece(const std::vector<TriRecord>& recs, double rate, std::vector<uint64_t>& outKeys,
                   std::vector<uint8_t>& outLocked, size_t& refused)
{
    Mesh m;
    std::vector<uint64_t> keys;
    std::unordered_map<uint64_t, uint32_t> index;
    index.reserve(recs.size());
    m.triangles.reserve(recs.size());
    for (const TriRecord& r : recs) {
        std::array<uint32_t, 3> t;
        for (int c = 0; c < 3; ++c) {
            auto [it, added] = index.emplace(r.key[c], uint32_t(m.points.size()));
            if (added) {
                m.points.push_back({r.p[c][0], r.p[c][1], r.p[c][2]});
                keys.push_back(r.key[c]);
            }
            t[c] = it->second;
        }
        m.triangles.push_back(t);
    }
    index = {};
    const std::vector<uint32_t> pinched = splitPinchedVertices(m, keys);
    // Cut vertices: ends of edges with other than two faces in this piece (on a closed surface,
    // exactly the vertices shared with another piece).
    std::unordered_map<uint64_t, uint32_t> edgeFaces;
    edgeFaces.reserve(3 * m.triangles.size() / 2);
    for (const auto& t : m.triangles)
        for (int e = 0; e < 3; ++e) {
            const uint64_t a = t[e], b = t[(e + 1) % 3];
            ++edgeFaces[std::min(a, b) << 32 | std::max(a, b)];
        }
    std::vector<uint8_t> locked(m.points.size(), 0);
    for (const auto& [edge, n] : edgeFaces)
        if (n != 2) locked[edge >> 32] = locked[edge & 0xffffffffu] = 1;
    edgeFaces = {};
    // The copies of a pinched vertex become one vertex again when stitched, so the piece must not
    // give two of them an edge to the same vertex: freeze their neighbourhoods (lock the 1-ring).
    if (!pinched.empty()) {
        std::vector<uint8_t> isPinched(m.points.size(), 0);
        for (uint32_t v : pinched) isPinched[v] = 1;
        for (const auto& t : m.triangles)
            if (isPinched[t[0]] || isPinched[t[1]] || isPinched[t[2]]) locked[t[0]] = locked[t[1]] = locked[t[2]] = 1;
    }

    // The paper's rule for uncontractible faces, F_t = (F - F_u) R + F_u: faces touching a locked
    // vertex cannot go, so only the rest is held to the rate (the final pass thins the seams).
    size_t lockedFaces = 0;
    for (const auto& t : m.triangles) lockedFaces += (locked[t[0]] | locked[t[1]] | locked[t[2]]) ? 1 : 0;
    const size_t faces = m.triangles.size();
    const size_t target = size_t(std::llround(double(faces - lockedFaces) * rate)) + lockedFaces;

    eval::TriMesh om = eval::toOpenMesh(m, refused);
    m = {};
    om.request_vertex_status();
    om.request_edge_status();
    om.request_face_status();
    om.request_face_normals();
    om.update_face_normals();
    OpenMesh::VPropHandleT<uint64_t> keyProp;
    om.add_property(keyProp);
    for (size_t v = 0; v < keys.size(); ++v) {
        const OpenMesh::VertexHandle vh{int(v)};
        om.property(keyProp, vh) = keys[v];
        if (locked[v]) om.status(vh).set_locked(true);
    }
    using Decimater = OpenMesh::Decimater::DecimaterT<eval::TriMesh>;
    Decimater dec(om);
    OpenMesh::Decimater::ModQuadricT<eval::TriMesh>::Handle quadric;
    dec.add(quadric);
    OpenMesh::Decimater::ModNormalFlippingT<eval::TriMesh>::Handle flipping;
    dec.add(flipping);
    ModKeepCutT<eval::TriMesh>::Handle keepCut;
    dec.add(keepCut);
    if (!dec.initialize()) throw std::runtime_error("decimater setup failed");
    if (target < om.n_faces()) dec.decimate_to_faces(0, target);
    om.garbage_collection();
    Mesh out = eval::fromOpenMesh(om);
    outKeys.resize(out.points.size());
    outLocked.resize(out.points.size());
    for (size_t v = 0; v < out.points.size(); ++v) {
        const OpenMesh::VertexHandle vh{int(v)};
        outKeys[v] = om.property(keyProp, vh);
        outLocked[v] = om.status(vh).locked();
    }
    return out;
}

} // namespace

int main(int argc, char** argv)
{
    CLI::App app{"baseline_cascade: out-of-core extraction to disk + cutting-based out-of-core simplification"};
    std::string input, output, gridName, tmp;
    double ratio = 0.2, iso = 0;
    uint64_t faces = 0;
    int k = 3;
    app.add_option("input", input, "Input .vdb")->required();
    app.add_option("-o,--output", output, "Write the simplified mesh here (.ply)");
    app.add_option("--grid", gridName, "Grid to mesh (default: the first float or double grid)");
    auto* isoOpt = app.add_option("--iso", iso, "Iso-value (default as vdb_isosimp)");
    app.add_option("-r,--ratio", ratio, "Decimation rate")->default_val(ratio);
    app.add_option("-f,--faces", faces, "Target face count (overrides ratio)");
    app.add_option("-k,--pieces", k, "Cut the bounding box into k x k x k pieces")->default_val(k)->check(CLI::Range(1, 16));
    app.add_option("--tmpdir", tmp, "Directory for the temporary files (default: $TMPDIR or /tmp)");
    CLI11_PARSE(app, argc, argv);
    try {
        TempDir dir(tmp.empty() ? fs::temp_directory_path() : fs::path(tmp));
        Stopwatch total;
        bench::resetHighWater();

        // 1. Extraction, streamed to disk.
        const Extraction ex = extractToSoup(input, gridName, *isoOpt ? &iso : nullptr, dir.path / "surface.soup");
        if (ex.faces == 0) throw std::runtime_error(input + ": no surface at the iso-value");
        const double extractSeconds = total.seconds();
        const double extractRss = bench::highWaterMb();
        malloc_trim(0);  // the volume is gone: do not count its freed pages in the next phase
        const bool separate = bench::resetHighWater();

        // 2. Cut into pieces by triangle centroid.
        Stopwatch simp;
        const uint64_t target = faces ? std::min(faces, ex.faces) : uint64_t(std::llround(ratio * double(ex.faces)));
        const int pieces = k * k * k;
        std::vector<std::unique_ptr<RecordFile>> pieceFiles;
        std::vector<std::vector<TriRecord>> pieceBuf(pieces);
        std::vector<uint64_t> pieceFaces(pieces, 0);
        for (int i = 0; i < pieces; ++i)
            pieceFiles.push_back(std::make_unique<RecordFile>(dir.path / ("piece" + std::to_string(i)), "wb"));
        {
            RecordFile soup(dir.path / "surface.soup", "rb");
            std::vector<TriRecord> chunk(1 << 16);
            while (size_t n = soup.read(chunk.data(), chunk.size())) {
                for (size_t i = 0; i < n; ++i) {
                    const TriRecord& r = chunk[i];
                    int cell[3];
                    for (int a = 0; a < 3; ++a) {
                        const double c = (double(r.p[0][a]) + r.p[1][a] + r.p[2][a]) / 3.0;
                        const double extent = ex.hi[a] - ex.lo[a];
                        const int ci = extent > 0 ? int((c - ex.lo[a]) / extent * k) : 0;
                        cell[a] = std::clamp(ci, 0, k - 1);
                    }
                    const int p = (cell[2] * k + cell[1]) * k + cell[0];
                    pieceBuf[p].push_back(r);
                    ++pieceFaces[p];
                    if (pieceBuf[p].size() == 4096) {
                        pieceFiles[p]->write(pieceBuf[p].data(), pieceBuf[p].size());
                        pieceBuf[p].clear();
                    }
                }
            }
        }
        fs::remove(dir.path / "surface.soup");
        uint64_t pieceBytes = 0;
        for (int p = 0; p < pieces; ++p) {
            pieceFiles[p]->write(pieceBuf[p].data(), pieceBuf[p].size());
            pieceFiles[p]->close();
            pieceBytes += pieceFiles[p]->bytes();
            pieceBuf[p] = {};
        }
        pieceFiles.clear();
        const double cutSeconds = simp.seconds();

        // 3. Each piece alone, cut locked; 4a. stitched on the locked vertices' keys.
        Mesh stitched;
        std::unordered_map<uint64_t, uint32_t> cutVertex;
        size_t refused = 0;
        uint64_t largestPiece = 0;
        int nonEmpty = 0;
        for (int p = 0; p < pieces; ++p) {
            if (pieceFaces[p] == 0) continue;
            ++nonEmpty;
            largestPiece = std::max(largestPiece, pieceFaces[p]);
            std::vector<TriRecord> recs(pieceFaces[p]);
            {
                RecordFile f(dir.path / ("piece" + std::to_string(p)), "rb");
                if (f.read(recs.data(), recs.size()) != recs.size()) throw std::runtime_error("short read of a piece file");
            }
            fs::remove(dir.path / ("piece" + std::to_string(p)));
            std::vector<uint64_t> keys;
            std::vector<uint8_t> locked;
            size_t pieceRefused = 0;
            const Mesh piece = simplifyPiece(recs, double(target) / double(ex.faces), keys, locked, pieceRefused);
            refused += pieceRefused;
            recs = {};
            std::vector<uint32_t> map(piece.points.size());
            for (size_t v = 0; v < piece.points.size(); ++v) {
                if (locked[v]) {
                    auto [it, added] = cutVertex.emplace(keys[v], uint32_t(stitched.points.size()));
                    if (added) stitched.points.push_back(piece.points[v]);
                    map[v] = it->second;
                } else {
                    map[v] = uint32_t(stitched.points.size());
                    stitched.points.push_back(piece.points[v]);
                }
            }
            for (const auto& t : piece.triangles) stitched.triangles.push_back({map[t[0]], map[t[1]], map[t[2]]});
        }
        cutVertex = {};
        const uint64_t stitchedFaces = stitched.triangles.size();
        const double piecesSeconds = simp.seconds() - cutSeconds;

        // 4b. Final pass over the stitched mesh, cut no longer locked.
        Stopwatch fin;
        size_t finalRefused = 0;
        const Mesh out = eval::decimateWithOpenMesh(stitched, target, &finalRefused);
        stitched = {};
        const double finalSeconds = fin.seconds();
        const double simplifySeconds = simp.seconds();
        // Resetting VmHWM also resets getrusage's maximum: the run's peak is the larger phase.
        const double simplifyRss = bench::highWaterMb();
        if (!output.empty()) writeMesh(out, output, "baseline_cascade");

        std::cout << bench::JsonLine()
                         .str("tool", "cascade")
                         .count("faces_full", ex.faces)
                         .count("faces_target", target)
                         .count("faces_out", out.triangles.size())
                         .count("pieces", nonEmpty)
                         .count("largest_piece_faces", largestPiece)
                         .count("faces_stitched", stitchedFaces)
                         .count("refused_faces_pieces", refused)
                         .count("refused_faces_final", finalRefused)
                         .count("disk_bytes", ex.bytes + pieceBytes)
                         .num("extract_seconds", extractSeconds)
                         .num("cut_seconds", cutSeconds)
                         .num("pieces_seconds", piecesSeconds)
                         .num("final_seconds", finalSeconds)
                         .num("simplify_seconds", simplifySeconds)
                         .num("seconds", total.seconds())
                         .num("extract_peak_rss_mb", extractRss, 1)
                         .num("simplify_peak_rss_mb", separate ? simplifyRss : peakRssMb(), 1)
                         .num("peak_rss_mb", separate ? std::max(extractRss, simplifyRss) : peakRssMb(), 1)
                         .text()
                  << std::endl;
        return 0;
    } catch (const std::exception& e) {
        std::cerr << "baseline_cascade: " << e.what() << "\n";
        return 1;
    }
}

#include "mesh_stats.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

namespace vdb_isosimp::eval {
namespace {

using Vec = std::array<double, 3>;

Vec toDouble(const std::array<float, 3>& p) { return {p[0], p[1], p[2]}; }
Vec sub(const Vec& a, const Vec& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const Vec& a, const Vec& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec cross(const Vec& a, const Vec& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double norm(const Vec& a) { return std::sqrt(dot(a, a)); }

// Fixed chunking keeps floating-point sums independent of the thread count: each chunk is summed
// serially, chunks are added in index order.
constexpr size_t kChunk = 1 << 14;

struct UnionFind {
    std::vector<uint32_t> parent;
    explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
    uint32_t find(uint32_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]]; // path halving
        return x;
    }
    void unite(uint32_t a, uint32_t b) {
        a = find(a);
        b = find(b);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
};

// Vertex -> incident faces, each face listed once per distinct corner vertex, in face order.
struct Incidence {
    std::vector<uint64_t> offset; // size V + 1
    std::vector<uint32_t> faces;
};

Incidence buildIncidence(const Mesh& mesh) {
    Incidence inc;
    const size_t V = mesh.points.size();
    inc.offset.assign(V + 1, 0);
    auto forDistinct = [](const std::array<uint32_t, 3>& t, auto&& fn) {
        fn(t[0]);
        if (t[1] != t[0]) fn(t[1]);
        if (t[2] != t[0] && t[2] != t[1]) fn(t[2]);
    };
    for (const auto& t : mesh.triangles) forDistinct(t, [&](uint32_t v) { ++inc.offset[v + 1]; });
    for (size_t v = 0; v < V; ++v) inc.offset[v + 1] += inc.offset[v];
    inc.faces.resize(inc.offset[V]);
    std::vector<uint64_t> fill(inc.offset.begin(), inc.offset.end() - 1);
    for (size_t f = 0; f < mesh.triangles.size(); ++f)
        forDistinct(mesh.triangles[f], [&](uint32_t v) { inc.faces[fill[v]++] = uint32_t(f); });
    return inc;
}

struct TopologyCounts {
    size_t edges = 0, boundary = 0, nonManifold = 0, misoriented = 0, nonManifoldVertices = 0;
    size_t referenced = 0;
    void add(const TopologyCounts& o) {
        edges += o.edges;
        boundary += o.boundary;
        nonManifold += o.nonManifold;
        misoriented += o.misoriented;
        nonManifoldVertices += o.nonManifoldVertices;
        referenced += o.referenced;
    }
};

// One side of a face at vertex v: the face (local number) reaches neighbour w along edge {v,w},
// leaving v (out) or arriving at v.
struct Side {
    uint32_t w;
    uint32_t localFace;
    bool out;
    bool operator<(const Side& o) const { return w < o.w || (w == o.w && localFace < o.localFace); }
};

// Edges are classified by their smaller endpoint; fans are counted at every vertex.
void countAtVertex(const Mesh& mesh, const Incidence& inc, uint32_t v, std::vector<Side>& sides,
                   std::vector<uint32_t>& fanParent, TopologyCounts& c) {
    const uint64_t begin = inc.offset[v], end = inc.offset[v + 1];
    if (begin == end) return;
    ++c.referenced;
    sides.clear();
    for (uint64_t i = begin; i < end; ++i) {
        const auto& t = mesh.triangles[inc.faces[i]];
        const uint32_t local = uint32_t(i - begin);
        for (int k = 0; k < 3; ++k) {
            if (t[size_t(k)] != v) continue;
            const uint32_t next = t[size_t((k + 1) % 3)], prev = t[size_t((k + 2) % 3)];
            if (next != v) sides.push_back({next, local, true});
            if (prev != v) sides.push_back({prev, local, false});
        }
    }
    std::sort(sides.begin(), sides.end());

    const uint32_t nFaces = uint32_t(end - begin);
    fanParent.resize(nFaces);
    std::iota(fanParent.begin(), fanParent.end(), 0u);
    auto find = [&](uint32_t x) {
        while (fanParent[x] != x) x = fanParent[x] = fanParent[fanParent[x]];
        return x;
    };
    for (size_t i = 0; i < sides.size();) {
        size_t j = i;
        size_t outs = 0;
        while (j < sides.size() && sides[j].w == sides[i].w) {
            outs += sides[j].out ? 1 : 0;
            // Faces sharing the edge {v,w} belong to the same fan around v.
            const uint32_t a = find(sides[i].localFace), b = find(sides[j].localFace);
            if (a != b) fanParent[std::max(a, b)] = std::min(a, b);
            ++j;
        }
        if (sides[i].w > v) {
            const size_t uses = j - i, ins = uses - outs;
            ++c.edges;
            if (uses == 1) ++c.boundary;
            else if (uses > 2) ++c.nonManifold;
            else if (outs == 2 || ins == 2) ++c.misoriented;
        }
        i = j;
    }
    size_t fans = 0;
    for (uint32_t f = 0; f < nFaces; ++f) fans += find(f) == f ? 1 : 0;
    if (fans > 1) ++c.nonManifoldVertices;
}

// Smallest interior angle in degrees; atan2 of |cross| and dot is accurate for tiny angles too,
// and yields 0 for degenerate triangles.
double minAngleDegrees(const Vec& a, const Vec& b, const Vec& c) {
    auto angle = [](const Vec& at, const Vec& p, const Vec& q) {
        const Vec u = sub(p, at), w = sub(q, at);
        return std::atan2(norm(cross(u, w)), dot(u, w));
    };
    const double m = std::min({angle(a, b, c), angle(b, c, a), angle(c, a, b)});
    return m * (180.0 / M_PI);
}

double percentile(const std::vector<float>& sorted, double p) {
    if (sorted.empty()) return 0;
    return sorted[size_t(p / 100.0 * double(sorted.size() - 1))];
}

} // namespace

MeshStats computeMeshStats(const Mesh& mesh, double zeroAreaEps) {
    MeshStats s;
    s.vertices = mesh.points.size();
    s.faces = mesh.triangles.size();
    const size_t F = s.faces;
    for (size_t f = 0; f < F; ++f)
        for (uint32_t v : mesh.triangles[f])
            if (v >= s.vertices)
                throw std::invalid_argument("triangle " + std::to_string(f) + " references vertex " +
                                            std::to_string(v) + " of " + std::to_string(s.vertices));

    // --- topology
    const Incidence inc = buildIncidence(mesh);
    const TopologyCounts topo = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, s.vertices, 4096), TopologyCounts{},
        [&](const tbb::blocked_range<size_t>& r, TopologyCounts c) {
            std::vector<Side> sides;
            std::vector<uint32_t> fanParent;
            for (size_t v = r.begin(); v != r.end(); ++v) countAtVertex(mesh, inc, uint32_t(v), sides, fanParent, c);
            return c;
        },
        [](TopologyCounts a, const TopologyCounts& b) {
            a.add(b);
            return a;
        });
    s.referencedVertices = topo.referenced;
    s.edges = topo.edges;
    s.boundaryEdges = topo.boundary;
    s.nonManifoldEdges = topo.nonManifold;
    s.misorientedEdges = topo.misoriented;
    s.nonManifoldVertices = topo.nonManifoldVertices;
    s.eulerCharacteristic = long(s.referencedVertices) - long(s.edges) + long(s.faces);

    {
        UnionFind uf(s.vertices);
        for (const auto& t : mesh.triangles) {
            uf.unite(t[0], t[1]);
            uf.unite(t[0], t[2]);
        }
        for (size_t v = 0; v < s.vertices; ++v)
            if (inc.offset[v + 1] > inc.offset[v] && uf.find(uint32_t(v)) == v) ++s.components;
    }

    if (F == 0) return s;

    // --- geometry: bounding box first (the volume is taken relative to its centre)
    for (int k = 0; k < 3; ++k) {
        s.bboxMin[k] = std::numeric_limits<double>::infinity();
        s.bboxMax[k] = -std::numeric_limits<double>::infinity();
    }
    for (size_t v = 0; v < s.vertices; ++v) {
        if (inc.offset[v + 1] == inc.offset[v]) continue;
        for (int k = 0; k < 3; ++k) {
            s.bboxMin[k] = std::min(s.bboxMin[k], double(mesh.points[v][size_t(k)]));
            s.bboxMax[k] = std::max(s.bboxMax[k], double(mesh.points[v][size_t(k)]));
        }
    }
    s.bboxDiagonal = norm({s.bboxMax[0] - s.bboxMin[0], s.bboxMax[1] - s.bboxMin[1], s.bboxMax[2] - s.bboxMin[2]});
    const Vec centre{0.5 * (s.bboxMin[0] + s.bboxMax[0]), 0.5 * (s.bboxMin[1] + s.bboxMax[1]),
                     0.5 * (s.bboxMin[2] + s.bboxMax[2])};

    struct Partial {
        double area = 0, volume = 0;
        size_t zeroArea = 0;
    };
    const size_t nChunks = (F + kChunk - 1) / kChunk;
    std::vector<Partial> partial(nChunks);
    std::vector<float> minAngles(F);
    tbb::parallel_for(size_t(0), nChunks, [&](size_t chunk) {
        Partial p;
        const size_t end = std::min(F, (chunk + 1) * kChunk);
        for (size_t f = chunk * kChunk; f < end; ++f) {
            const auto& t = mesh.triangles[f];
            const Vec a = sub(toDouble(mesh.points[t[0]]), centre);
            const Vec b = sub(toDouble(mesh.points[t[1]]), centre);
            const Vec c = sub(toDouble(mesh.points[t[2]]), centre);
            const double area = 0.5 * norm(cross(sub(b, a), sub(c, a)));
            p.area += area;
            p.volume += dot(a, cross(b, c)) / 6.0;
            if (area <= zeroAreaEps) ++p.zeroArea;
            minAngles[f] = float(minAngleDegrees(a, b, c));
        }
        partial[chunk] = p;
    });
    for (const Partial& p : partial) {
        s.area += p.area;
        s.signedVolume += p.volume;
        s.zeroAreaFaces += p.zeroArea;
    }
    tbb::parallel_sort(minAngles.begin(), minAngles.end());
    s.minAngleP1 = percentile(minAngles, 1);
    s.minAngleP5 = percentile(minAngles, 5);
    s.minAngleP50 = percentile(minAngles, 50);
    return s;
}

} // namespace vdb_isosimp::eval

#include "core/marching_cubes.h"

#include "core/modifiability.h"

#include <cmath>
#include <stdexcept>

namespace vdb_isosimp {

int CubeGeometry::edgeCorner(int e, int end)
{
    const int a = e / 4, u = (a + 1) % 3, v = (a + 2) % 3;
    const int lo = u < v ? u : v, hi = u < v ? v : u;
    const int c = (((e % 4) & 1) << lo) | ((((e % 4) >> 1) & 1) << hi);
    return end ? (c | (1 << a)) : c;
}

namespace {

using V3 = std::array<double, 3>;
V3 cornerPos(int c) { return {double(c & 1), double((c >> 1) & 1), double((c >> 2) & 1)}; }
V3 edgeMid(int e)
{
    V3 a = cornerPos(CubeGeometry::edgeCorner(e, 0)), b = cornerPos(CubeGeometry::edgeCorner(e, 1));
    return {(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2};
}
V3 sub(V3 a, V3 b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
V3 cross(V3 a, V3 b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
double dot(V3 a, V3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// True when edges a and b lie on a common face of the cube.
bool shareFace(int a, int b)
{
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side < 2; ++side) {
            auto on = [&](int e) {
                return CubeGeometry::edgeAxis(e) != axis && ((CubeGeometry::edgeCorner(e, 0) >> axis) & 1) == side;
            };
            if (on(a) && on(b)) return true;
        }
    return false;
}

// Minimum-total-chord-length triangulation of a loop (dynamic programming over sub-polygons), with
// chords between points on a common face forbidden. Loops have at most 12 points.
void triangulateLoop(const int* loop, int n, McCase& out)
{
    constexpr double kForbidden = 1e9;
    auto chordCost = [&](int i, int j) {
        if ((j - i + n) % n == 1 || (i - j + n) % n == 1) return 0.0;  // a loop side, not a chord
        if (shareFace(loop[i], loop[j])) return kForbidden;
        const V3 d = sub(edgeMid(loop[i]), edgeMid(loop[j]));
        return std::sqrt(dot(d, d));
    };
    double cost[12][12] = {};
    int split[12][12] = {};
    for (int gap = 2; gap < n; ++gap)
        for (int i = 0; i + gap < n; ++i) {
            const int j = i + gap;
            cost[i][j] = 2 * kForbidden * 12;
            for (int k = i + 1; k < j; ++k) {
                const double c = cost[i][k] + cost[k][j] + chordCost(i, k) + chordCost(k, j);
                if (c < cost[i][j]) { cost[i][j] = c; split[i][j] = k; }
            }
        }
    if (cost[0][n - 1] >= kForbidden) throw std::logic_error("marching cubes: no crack-free triangulation");
    struct Span { int i, j; };
    Span stack[12];
    int top = 0;
    stack[top++] = {0, n - 1};
    while (top) {
        const Span s = stack[--top];
        if (s.j - s.i < 2) continue;
        const int k = split[s.i][s.j];
        out.triangles[out.triangleCount++] = {uint8_t(loop[s.i]), uint8_t(loop[s.j]), uint8_t(loop[k])};
        stack[top++] = {s.i, k};
        stack[top++] = {k, s.j};
    }
}

McCase buildCase(int mask)
{
    auto in = [mask](int c) { return (mask >> c) & 1; };
    auto crosses = [&](int e) { return in(CubeGeometry::edgeCorner(e, 0)) != in(CubeGeometry::edgeCorner(e, 1)); };
    int next[12];
    for (int& n : next) n = -1;

    for (int axis = 0; axis < 3; ++axis) {
        for (int side = 0; side < 2; ++side) {
            V3 normal{0, 0, 0};
            normal[axis] = side ? 1.0 : -1.0;
            // The four face edges: edges along the two other axes whose corners have bit `axis` == side.
            int faceEdges[4], n = 0;
            for (int e = 0; e < 12; ++e) {
                if (CubeGeometry::edgeAxis(e) == axis) continue;
                if (((CubeGeometry::edgeCorner(e, 0) >> axis) & 1) == side) faceEdges[n++] = e;
            }
            // Pair crossing edges: each inside corner of the face is cut off by the segment joining its
            // two face edges when both cross; with exactly two crossings they simply pair up.
            std::array<std::array<int, 2>, 2> segs;
            int segCount = 0, crossing[4], nc = 0;
            for (int e : faceEdges) if (crosses(e)) crossing[nc++] = e;
            if (nc == 2) {
                segs[segCount++] = {crossing[0], crossing[1]};
            } else if (nc == 4) {
                for (int c = 0; c < 8; ++c) {
                    if (((c >> axis) & 1) != side || !in(c)) continue;
                    int pair[2], k = 0;
                    for (int e : faceEdges)
                        if (CubeGeometry::edgeCorner(e, 0) == c || CubeGeometry::edgeCorner(e, 1) == c) pair[k++] = e;
                    segs[segCount++] = {pair[0], pair[1]};
                }
            }
            // Orient each segment so the inside corners lie to its left, seen from outside the cube:
            // the loops then run consistently around the inside patches of the cube's surface.
            for (int s = 0; s < segCount; ++s) {
                const int e1 = segs[s][0], e2 = segs[s][1];
                const int c = in(CubeGeometry::edgeCorner(e1, 0)) ? CubeGeometry::edgeCorner(e1, 0)
                                                                  : CubeGeometry::edgeCorner(e1, 1);
                const V3 p = edgeMid(e1), q = edgeMid(e2);
                if (dot(cross(sub(q, p), sub(cornerPos(c), p)), normal) > 0) next[e1] = e2;
                else next[e2] = e1;
            }
        }
    }
    // Walk the loops and triangulate them. A loop runs counter-clockwise around the inside patch seen
    // from outside, so its right-hand normal points into the inside region: emit the reverse to face
    // outward. Chords may not join two points on a common cube face: the neighbour across that face
    // could draw the same chord, and the welded edge would then carry four triangles.
    McCase out;
    bool seen[12] = {};
    for (int start = 0; start < 12; ++start) {
        if (next[start] < 0 || seen[start]) continue;
        int loop[12], len = 0;
        for (int e = start; !seen[e]; e = next[e]) { seen[e] = true; loop[len++] = e; }
        triangulateLoop(loop, len, out);
    }
    return out;
}

std::array<McCase, 256> buildTable()
{
    std::array<McCase, 256> t;
    for (int m = 0; m < 256; ++m) t[m] = buildCase(m);
    return t;
}

} // namespace

const std::array<McCase, 256>& mcTable()
{
    static const std::array<McCase, 256> table = buildTable();
    return table;
}

std::array<double, 3> Affine::apply(const std::array<double, 3>& p) const
{
    return {m[0] * p[0] + m[1] * p[1] + m[2] * p[2] + m[3], m[4] * p[0] + m[5] * p[1] + m[6] * p[2] + m[7],
            m[8] * p[0] + m[9] * p[1] + m[10] * p[2] + m[11]};
}

double Affine::determinant() const
{
    return m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) +
           m[2] * (m[4] * m[9] - m[5] * m[8]);
}

std::array<uint8_t, 512> blockCases(const BlockSamples& s, const Classifier& c)
{
    constexpr int N = BlockSamples::N;
    std::array<uint8_t, N * N * N> in;
    for (size_t i = 0; i < in.size(); ++i) in[i] = c.inside(s.values[i]);
    std::array<uint8_t, 512> cases;
    for (int z = 0; z < 8; ++z)
        for (int y = 0; y < 8; ++y)
            for (int x = 0; x < 8; ++x) {
                const uint8_t* o = &in[(z * N + y) * N + x];
                cases[(z * 8 + y) * 8 + x] = uint8_t(o[0] | o[1] << 1 | o[N] << 2 | o[N + 1] << 3 | o[N * N] << 4 |
                                                     o[N * N + 1] << 5 | o[N * N + N] << 6 | o[N * N + N + 1] << 7);
            }
    return cases;
}

uint64_t countBlockTriangles(const BlockSamples& s, const Classifier& c)
{
    const auto& table = mcTable();
    uint64_t n = 0;
    for (uint8_t mask : blockCases(s, c)) n += table[mask].triangleCount;
    return n;
}

void extractBlock(const BlockSamples& s, const Classifier& c, const Affine& toWorld, bool flipWinding,
                  BlockMesh& out)
{
    constexpr int N = BlockSamples::N;
    const auto& table = mcTable();
    out.keys.clear();
    out.positions.clear();
    out.finalAfterBlock.clear();
    out.triangles.clear();
    // Local weld: one slot per (corner, axis) of the 9^3 sample lattice.
    std::array<int32_t, N * N * N * 3> slot;
    slot.fill(-1);

    auto vertexOf = [&](int x, int y, int z, int e) -> uint32_t {
        const int c0 = CubeGeometry::edgeCorner(e, 0), axis = CubeGeometry::edgeAxis(e);
        const int ex = x + (c0 & 1), ey = y + ((c0 >> 1) & 1), ez = z + ((c0 >> 2) & 1);
        int32_t& id = slot[((ez * N + ey) * N + ex) * 3 + axis];
        if (id >= 0) return uint32_t(id);
        id = int32_t(out.keys.size());
        const std::array<int32_t, 3> gmin{s.origin[0] + ex, s.origin[1] + ey, s.origin[2] + ez};
        // Interpolate from the edge's min end, the same way in every cell that shares the edge.
        const double v0 = s.at(ex, ey, ez);
        const double v1 = s.at(ex + (axis == 0), ey + (axis == 1), ez + (axis == 2));
        const double t = (c.iso - v0) / (v1 - v0);
        std::array<double, 3> p{double(gmin[0]), double(gmin[1]), double(gmin[2])};
        p[axis] += t;
        out.keys.push_back(makeEdgeKey(gmin[0], gmin[1], gmin[2], axis));
        out.positions.push_back(toWorld.apply(p));
        out.finalAfterBlock.push_back(finalAfterBlock(gmin, s.origin));
        return uint32_t(id);
    };

    const std::array<uint8_t, 512> cases = blockCases(s, c);
    for (int z = 0; z < 8; ++z)
        for (int y = 0; y < 8; ++y)
            for (int x = 0; x < 8; ++x) {
                const McCase& mc = table[cases[(z * 8 + y) * 8 + x]];
                for (int t = 0; t < mc.triangleCount; ++t) {
                    std::array<uint32_t, 3> tri{vertexOf(x, y, z, mc.triangles[t][0]),
                                                vertexOf(x, y, z, mc.triangles[t][1]),
                                                vertexOf(x, y, z, mc.triangles[t][2])};
                    if (flipWinding) std::swap(tri[1], tri[2]);
                    out.triangles.push_back(tri);
                }
            }
}

} // namespace vdb_isosimp

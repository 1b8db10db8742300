#include "core/piece_bytes.h"

#include <cstring>
#include <stdexcept>
#include <type_traits>

namespace vdb_isosimp {

namespace {

constexpr uint64_t kMagic = 0x32656365695076ull;  // "vPiece2"

class Writer {
public:
    explicit Writer(std::vector<char>& out) : mOut(out) {}
    template <typename T>
    void put(const T& x)
    {
        static_assert(std::is_arithmetic<T>::value, "fields one by one: no padding bytes on the wire");
        const char* p = reinterpret_cast<const char*>(&x);
        mOut.insert(mOut.end(), p, p + sizeof x);
    }

private:
    std::vector<char>& mOut;
};

class Reader {
public:
    Reader(const char* in, size_t size) : mP(in), mEnd(in + size) {}
    template <typename T>
    T get()
    {
        if (size_t(mEnd - mP) < sizeof(T)) throw std::runtime_error("merge tree piece: bytes end early");
        T x;
        std::memcpy(&x, mP, sizeof x);
        mP += sizeof x;
        return x;
    }
    // A count of records of at least `recordBytes` each, checked against what is left.
    uint64_t count(size_t recordBytes)
    {
        const uint64_t n = get<uint64_t>();
        if (n > uint64_t(mEnd - mP) / recordBytes) throw std::runtime_error("merge tree piece: bytes end early");
        return n;
    }

private:
    const char* mP;
    const char* mEnd;
};

} // namespace

void writePieceBytes(SlabPiece&& piece, std::vector<char>& out)
{
    Writer w(out);
    MeshPiece& m = piece.mesh;
    out.reserve(out.size() + 128 + 44 * piece.stats.trace.size() + 105 * m.vertices.size() + 12 * m.faces.size() +
                12 * m.open.size() + 13 * m.queue.size() + 9 * m.refused.size() +
                12 * (m.retired.points.size() + m.retired.triangles.size()) + 8 * m.pinned.size());
    w.put(kMagic);
    w.put(piece.facesGenerated);
    w.put(uint8_t(piece.roomSpent));
    w.put(piece.stats.decimations);
    w.put(piece.stats.maxIntermediateFaces);
    w.put(piece.stats.maxUncontractibleFaces);
    w.put(piece.stats.maxErrorAccepted);
    const QueueWork& work = piece.stats.work;
    for (uint64_t x : {work.pops, work.dead, work.stale, work.attempts, work.collapses}) w.put(x);
    w.put(uint64_t(piece.stats.trace.size()));
    for (const DecimationRecord& r : piece.stats.trace) {
        w.put(r.facesGenerated);
        w.put(r.facesBefore);
        w.put(r.facesAfter);
        w.put(r.uncontractible);
        w.put(r.target);
        w.put(r.slab);
    }
    w.put(uint64_t(m.vertices.size()));
    for (size_t i = 0; i < m.vertices.size(); ++i) {
        const MeshPiece::Vertex& v = m.vertices[i];
        for (double x : v.p) w.put(x);
        for (double x : v.q.q) w.put(x);
        w.put(uint8_t(v.final));
        m.vertices.releaseThrough(i);
    }
    w.put(uint64_t(m.faces.size()));
    for (size_t i = 0; i < m.faces.size(); ++i) {
        for (uint32_t x : m.faces[i]) w.put(x);
        m.faces.releaseThrough(i);
    }
    w.put(uint64_t(m.open.size()));
    for (const auto& [key, id] : m.open) {
        w.put(key);
        w.put(id);
    }
    w.put(uint64_t(m.queue.size()));
    for (size_t i = 0; i < m.queue.size(); ++i) {
        const MeshPiece::Queued& c = m.queue[i];
        w.put(c.costBits);
        w.put(c.a);
        w.put(c.b);
        w.put(uint8_t(c.stale));
        m.queue.releaseThrough(i);
    }
    w.put(m.forgetFromBits);
    w.put(uint64_t(m.refused.size()));
    for (const auto& r : m.refused) {
        w.put(r.a);
        w.put(r.b);
        w.put(uint8_t(r.why));
    }
    w.put(uint64_t(m.drift.size()));
    for (size_t i = 0; i < m.drift.size(); ++i) w.put(m.drift[i]);
    w.put(uint64_t(m.attributes.size()));
    for (size_t i = 0; i < m.attributes.size(); ++i) {
        const AttributeQuadric& a = m.attributes[i];
        for (double x : a.gg) w.put(x);
        for (double x : a.g) w.put(x);
        for (double x : a.gd) w.put(x);
        for (double x : {a.w, a.d, a.dd}) w.put(x);
    }
    w.put(uint64_t(m.retired.points.size()));
    for (size_t i = 0; i < m.retired.points.size(); ++i) {
        for (float x : m.retired.points[i]) w.put(x);
        m.retired.points.releaseThrough(i);
    }
    w.put(uint64_t(m.retired.triangles.size()));
    for (size_t i = 0; i < m.retired.triangles.size(); ++i) {
        for (uint32_t x : m.retired.triangles[i]) w.put(x);
        m.retired.triangles.releaseThrough(i);
    }
    w.put(uint64_t(m.pinned.size()));
    for (const auto& [v, at] : m.pinned) {
        w.put(v);
        w.put(at);
    }
    piece = SlabPiece{};
}

SlabPiece readPieceBytes(const char* bytes, size_t size)
{
    Reader r(bytes, size);
    SlabPiece piece;
    if (r.get<uint64_t>() != kMagic) throw std::runtime_error("merge tree piece: not a piece");
    piece.facesGenerated = r.get<uint64_t>();
    piece.roomSpent = r.get<uint8_t>() != 0;
    piece.stats.decimations = r.get<uint64_t>();
    piece.stats.maxIntermediateFaces = r.get<uint64_t>();
    piece.stats.maxUncontractibleFaces = r.get<uint64_t>();
    piece.stats.maxErrorAccepted = r.get<double>();
    QueueWork& work = piece.stats.work;
    for (uint64_t* x : {&work.pops, &work.dead, &work.stale, &work.attempts, &work.collapses}) *x = r.get<uint64_t>();
    piece.stats.trace.resize(r.count(5 * 8 + 4));
    for (DecimationRecord& d : piece.stats.trace) {
        d.facesGenerated = r.get<uint64_t>();
        d.facesBefore = r.get<uint64_t>();
        d.facesAfter = r.get<uint64_t>();
        d.uncontractible = r.get<uint64_t>();
        d.target = r.get<uint64_t>();
        d.slab = r.get<uint32_t>();
    }
    MeshPiece& m = piece.mesh;
    const uint64_t vertices = r.count(13 * 8 + 1);
    for (uint64_t i = 0; i < vertices; ++i) {
        MeshPiece::Vertex& v = m.vertices.emplace_back();
        for (double& x : v.p) x = r.get<double>();
        for (double& x : v.q.q) x = r.get<double>();
        v.final = r.get<uint8_t>() != 0;
    }
    const uint64_t faces = r.count(12);
    for (uint64_t i = 0; i < faces; ++i) {
        auto& f = m.faces.emplace_back();
        for (uint32_t& x : f) {
            x = r.get<uint32_t>();
            if (x >= vertices) throw std::runtime_error("merge tree piece: a face names a missing vertex");
        }
    }
    m.open.resize(r.count(12));
    for (auto& [key, id] : m.open) {
        key = r.get<EdgeKey>();
        id = r.get<uint32_t>();
        if (id >= vertices) throw std::runtime_error("merge tree piece: an open vertex is missing");
    }
    for (uint64_t i = 0, n = r.count(13); i < n; ++i) {
        MeshPiece::Queued& c = m.queue.emplace_back();
        c.costBits = r.get<uint32_t>();
        c.a = r.get<uint32_t>();
        c.b = r.get<uint32_t>();
        c.stale = r.get<uint8_t>() != 0;
        if (c.a >= vertices || c.b >= vertices) throw std::runtime_error("merge tree piece: a queued edge is missing");
    }
    m.forgetFromBits = r.get<uint32_t>();
    m.refused.resize(r.count(9));
    for (auto& x : m.refused) {
        x.a = r.get<uint32_t>();
        x.b = r.get<uint32_t>();
        const uint8_t why = r.get<uint8_t>();
        if (why > uint8_t(Refusal::Bound)) throw std::runtime_error("merge tree piece: a refusal of no known kind");
        x.why = Refusal(why);
        if (x.a >= vertices || x.b >= vertices) throw std::runtime_error("merge tree piece: a refused edge is missing");
    }
    const uint64_t drift = r.count(4);
    if (drift != 0 && drift != vertices) throw std::runtime_error("merge tree piece: drift for some vertices only");
    for (uint64_t i = 0; i < drift; ++i) m.drift.emplace_back() = r.get<float>();
    const uint64_t attributes = r.count(15 * 8);
    if (attributes != 0 && attributes != vertices) throw std::runtime_error("merge tree piece: attributes for some vertices only");
    for (uint64_t i = 0; i < attributes; ++i) {
        AttributeQuadric& a = m.attributes.emplace_back();
        for (double& x : a.gg) x = r.get<double>();
        for (double& x : a.g) x = r.get<double>();
        for (double& x : a.gd) x = r.get<double>();
        a.w = r.get<double>();
        a.d = r.get<double>();
        a.dd = r.get<double>();
    }
    const uint64_t points = r.count(12);
    for (uint64_t i = 0; i < points; ++i)
        for (float& x : m.retired.points.emplace_back()) x = r.get<float>();
    for (uint64_t i = 0, n = r.count(12); i < n; ++i)
        for (uint32_t& x : m.retired.triangles.emplace_back()) {
            x = r.get<uint32_t>();
            if (x >= points) throw std::runtime_error("merge tree piece: a retired face names a missing point");
        }
    m.pinned.resize(r.count(8));
    for (auto& [v, at] : m.pinned) {
        v = r.get<uint32_t>();
        at = r.get<uint32_t>();
        if (v >= vertices || at >= m.retired.points.size()) throw std::runtime_error("merge tree piece: a pinned vertex is missing");
    }
    return piece;
}

} // namespace vdb_isosimp

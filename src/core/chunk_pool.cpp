#include "core/chunk_pool.h"

#include <mutex>
#include <new>
#include <vector>

namespace vdb_isosimp {

namespace {

struct Waiting {
    void* p;
    size_t bytes, align;
};

struct Pool {
    // Room for as many chunks as the cap can hold, so that listing a freed chunk never allocates.
    Pool() { chunks.reserve(ChunkPool::kMaxCachedBytes / ChunkPool::kMinBytes); }
    std::mutex mutex;
    std::vector<Waiting> chunks;  // a handful of sizes: a linear search finds one
    size_t bytes = 0;
};

Pool& pool()
{
    static Pool* p = new Pool;  // never destroyed: chunks may be freed by static destructors after main
    return *p;
}

} // namespace

void* ChunkPool::allocate(size_t bytes, size_t align)
{
    if (bytes >= kMinBytes) {
        Pool& p = pool();
        std::lock_guard<std::mutex> lock(p.mutex);
        for (size_t i = p.chunks.size(); i-- > 0;) {
            if (p.chunks[i].bytes != bytes || p.chunks[i].align != align) continue;
            void* chunk = p.chunks[i].p;
            p.chunks[i] = p.chunks.back();
            p.chunks.pop_back();
            p.bytes -= bytes;
            return chunk;
        }
    }
    return ::operator new(bytes, std::align_val_t(align));
}

void ChunkPool::free(void* chunk, size_t bytes, size_t align) noexcept
{
    if (!chunk) return;
    if (bytes >= kMinBytes) {
        Pool& p = pool();
        std::lock_guard<std::mutex> lock(p.mutex);
        if (p.bytes + bytes <= kMaxCachedBytes) {
            p.chunks.push_back({chunk, bytes, align});
            p.bytes += bytes;
            return;
        }
    }
    ::operator delete(chunk, std::align_val_t(align));
}

size_t ChunkPool::cachedBytes()
{
    Pool& p = pool();
    std::lock_guard<std::mutex> lock(p.mutex);
    return p.bytes;
}

void ChunkPool::release()
{
    Pool& p = pool();
    std::lock_guard<std::mutex> lock(p.mutex);
    for (const Waiting& w : p.chunks) ::operator delete(w.p, std::align_val_t(w.align));
    p.chunks.clear();  // keeps its room
    p.bytes = 0;
}

} // namespace vdb_isosimp

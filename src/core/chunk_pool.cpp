#include "core/chunk_pool.h"

#include "core/huge_pages.h"

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <new>
#include <vector>

namespace vdb_isosimp {

namespace {

// A mapping of whole huge pages cut into equal slots of one chunk size.
struct Region {
    char* base = nullptr;
    size_t bytes = 0;  // the mapping, a multiple of kHugePage
    uint32_t slots = 0, fresh = 0, used = 0;  // slots never handed out start at `fresh`
    std::vector<uint32_t> freed;              // room for every slot: listing one never allocates
    Region *prev = nullptr, *next = nullptr;  // in its size's list of regions with room
};

struct SizeClass {
    size_t slotBytes = 0;
    Region* withRoom = nullptr;  // the regions with a slot not in use, the latest first

    void add(Region* r)
    {
        r->prev = nullptr;
        r->next = withRoom;
        if (withRoom) withRoom->prev = r;
        withRoom = r;
    }
    void remove(Region* r)
    {
        (r->prev ? r->prev->next : withRoom) = r->next;
        if (r->next) r->next->prev = r->prev;
    }
};

// Up to four huge pages: as few as leave at most 5 % unused (vertex geometry's 416 KiB chunks: 19 in 8 MiB).
size_t regionBytesFor(size_t slot)
{
    for (size_t k = 1; k < 4; ++k) {
        const size_t bytes = k * kHugePage;
        if ((bytes % slot) * 20 <= bytes) return bytes;  // at most 5 % unused
    }
    return 4 * kHugePage;
}

struct Pool {
    std::mutex mutex;
    std::vector<SizeClass> classes;
    std::map<char*, Region*> regions;  // by base
    size_t freeBytes = 0;
};

Pool& pool()
{
    static Pool* p = new Pool;  // never destroyed: chunks may be freed by static destructors after main
    return *p;
}

// The size's list of regions, made at its first chunk.
SizeClass& sizeClass(Pool& p, size_t slotBytes)
{
    for (SizeClass& c : p.classes)
        if (c.slotBytes == slotBytes) return c;
    p.classes.push_back({slotBytes, nullptr});
    return p.classes.back();
}

// A new region, listed in the pool's map; nothing is left mapped or allocated if any step throws.
Region* mapRegion(Pool& p, size_t slotBytes)
{
    auto r = std::make_unique<Region>();
    r->bytes = regionBytesFor(slotBytes);
    r->slots = uint32_t(r->bytes / slotBytes);
    r->freed.reserve(r->slots);
    r->base = static_cast<char*>(mapHugePages(r->bytes));
    try {
        p.regions.emplace(r->base, r.get());
    } catch (...) {
        unmapHugePages(r->base, r->bytes);
        throw;
    }
    return r.release();
}

// A slot at a multiple of its size from a huge page's boundary is aligned to `align`.
bool pooled(size_t bytes, size_t align)
{
    return kChunksInRegions && bytes >= ChunkPool::kMinBytes && bytes <= kHugePage && bytes % align == 0 && kHugePage % align == 0;
}

} // namespace

void* ChunkPool::allocate(size_t bytes, size_t align)
{
    if (!pooled(bytes, align)) return ::operator new(bytes, std::align_val_t(align));
    Pool& p = pool();
    std::lock_guard<std::mutex> lock(p.mutex);
    SizeClass& c = sizeClass(p, bytes);
    if (!c.withRoom) {
        Region* r = mapRegion(p, bytes);
        c.add(r);
        p.freeBytes += size_t(r->slots) * bytes;
    }
    Region* r = c.withRoom;
    uint32_t slot;
    if (!r->freed.empty()) {
        slot = r->freed.back();
        r->freed.pop_back();
    } else {
        slot = r->fresh++;
    }
    ++r->used;
    p.freeBytes -= bytes;
    if (r->used == r->slots) c.remove(r);
    return r->base + size_t(slot) * bytes;
}

void ChunkPool::free(void* chunk, size_t bytes, size_t align) noexcept
{
    if (!chunk) return;
    if (!pooled(bytes, align)) {
        ::operator delete(chunk, std::align_val_t(align));
        return;
    }
    Pool& p = pool();
    std::lock_guard<std::mutex> lock(p.mutex);
    char* c = static_cast<char*>(chunk);
    auto it = p.regions.upper_bound(c);
    --it;
    Region* r = it->second;
    SizeClass& s = sizeClass(p, bytes);  // listed since the chunk's allocation: no allocation here
    if (r->used == r->slots) s.add(r);
    r->freed.push_back(uint32_t(size_t(c - r->base) / bytes));
    --r->used;
    p.freeBytes += bytes;
    if (r->used == 0) {
        s.remove(r);
        p.freeBytes -= size_t(r->slots) * bytes;
        unmapHugePages(r->base, r->bytes);
        p.regions.erase(it);
        delete r;
    }
}

size_t ChunkPool::idleBytes()
{
    Pool& p = pool();
    std::lock_guard<std::mutex> lock(p.mutex);
    return p.freeBytes;
}

size_t ChunkPool::mappedBytes()
{
    Pool& p = pool();
    std::lock_guard<std::mutex> lock(p.mutex);
    size_t bytes = 0;
    for (const auto& [base, r] : p.regions) bytes += r->bytes;
    return bytes;
}

} // namespace vdb_isosimp

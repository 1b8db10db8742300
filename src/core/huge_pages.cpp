#include "core/huge_pages.h"

#include <sys/mman.h>

#include <cstdint>
#include <new>

namespace vdb_isosimp {

void* mapHugePages(size_t bytes)
{
    // Mapped one huge page longer, then trimmed to the boundary: mmap aligns to 4 KiB only.
    void* m = mmap(nullptr, bytes + kHugePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (m == MAP_FAILED) throw std::bad_alloc();
    char* raw = static_cast<char*>(m);
    char* base = reinterpret_cast<char*>((reinterpret_cast<uintptr_t>(raw) + kHugePage - 1) & ~uintptr_t(kHugePage - 1));
    if (base > raw) munmap(raw, size_t(base - raw));
    char* end = raw + bytes + kHugePage;
    if (end > base + bytes) munmap(base + bytes, size_t(end - (base + bytes)));
    madvise(base, bytes, MADV_HUGEPAGE);  // a host without transparent huge pages refuses: 4 KiB pages then
    return base;
}

void unmapHugePages(void* p, size_t bytes) noexcept
{
    if (p) munmap(p, bytes);
}

void adviseHugePages(void* p, size_t bytes) noexcept
{
    const uintptr_t from = (reinterpret_cast<uintptr_t>(p) + kHugePage - 1) & ~uintptr_t(kHugePage - 1);
    const uintptr_t to = (reinterpret_cast<uintptr_t>(p) + bytes) & ~uintptr_t(kHugePage - 1);
    if (to > from) madvise(reinterpret_cast<void*>(from), to - from, MADV_HUGEPAGE);
}

} // namespace vdb_isosimp

// Memory the kernel may back with 2 MiB pages (transparent huge pages, which Linux gives a mapping that
// asks for them with madvise). A run lets go of and takes again hundreds of megabytes of large arrays:
// every 4 KiB page of fresh memory is a page fault on first touch, and on the virtual machines these
// runs are measured on a fault costs about 13 us; a 2 MiB page costs 0.26 us per 4 KiB once the host has
// backed it, 4-8 us before (benchmarks/page_fault_bench.cpp, docs/perf.md). Where the host gives no huge
// pages, the same mappings take 4 KiB pages as before.
#pragma once
#include <cstddef>

namespace vdb_isosimp {

constexpr size_t kHugePage = size_t(2) << 20;

// A zeroed mapping of `bytes` (a multiple of kHugePage) that starts on a kHugePage boundary and asks for
// huge pages. Throws std::bad_alloc.
void* mapHugePages(size_t bytes);
void unmapHugePages(void* p, size_t bytes) noexcept;
// Asks for huge pages on the whole kHugePage-aligned pages inside [p, p + bytes): for an array just
// allocated by someone else's allocator (the output mesh's) and not yet written.
void adviseHugePages(void* p, size_t bytes) noexcept;

} // namespace vdb_isosimp

// What fresh memory costs on this host: SIZE MiB mapped, every 4 KiB page written once, unmapped, six
// rounds, once as plain 4 KiB pages (what glibc gives a chunk of 128 KiB or more) and once through
// core/huge_pages.h (what the decimator's chunk regions and pooled arrays take), alternating. The first
// huge-page round pays the host for backing memory it has not given the guest before; later rounds
// show what a reused 2 MiB page costs. docs/perf.md quotes the microseconds per 4 KiB page.
// Usage: page_fault_bench [SIZE_MIB]   (default 256)
#include "core/huge_pages.h"

#include <sys/mman.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>

namespace {

double touch(char* p, size_t bytes)
{
    const auto t0 = std::chrono::steady_clock::now();
    for (size_t i = 0; i < bytes; i += 4096) p[i] = 1;
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace

int main(int argc, char** argv)
{
    const size_t mib = argc > 1 ? std::strtoul(argv[1], nullptr, 10) : 256;
    const size_t bytes = (mib << 20) / vdb_isosimp::kHugePage * vdb_isosimp::kHugePage;
    if (bytes == 0) {
        std::fprintf(stderr, "page_fault_bench: SIZE_MIB must be at least 2\n");
        return 2;
    }
    const double pages = double(bytes / 4096);
    std::printf("round  4KiB pages s  us/page  huge pages s  us/4KiB  ratio\n");
    for (int round = 0; round < 6; ++round) {
        void* m = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (m == MAP_FAILED) {
            std::perror("page_fault_bench: mmap");
            return 1;
        }
        const double small = touch(static_cast<char*>(m), bytes);
        munmap(m, bytes);
        void* h = vdb_isosimp::mapHugePages(bytes);
        const double huge = touch(static_cast<char*>(h), bytes);
        vdb_isosimp::unmapHugePages(h, bytes);
        std::printf("%5d  %12.3f  %7.2f  %12.3f  %7.2f  %5.1f\n", round, small, 1e6 * small / pages, huge,
                    1e6 * huge / pages, small / huge);
    }
    return 0;
}

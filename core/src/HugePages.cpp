#include "isohex/core/HugePages.hpp"

#include <cstdint>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace isohex::detail {

namespace {
std::size_t rounded(std::size_t bytes) { return (bytes + kHugePage - 1) & ~(kHugePage - 1); }
}  // namespace

void adviseHugePages(const void* p, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    constexpr std::uintptr_t kHuge = kHugePage;
    const auto begin = (reinterpret_cast<std::uintptr_t>(p) + kHuge - 1) & ~(kHuge - 1);
    const auto end = (reinterpret_cast<std::uintptr_t>(p) + bytes) & ~(kHuge - 1);
    if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#else
    (void)p;
    (void)bytes;
#endif
}

void* allocateHuge(std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (bytes >= kHugeFrom) {
        // Map one page more than needed, then trim to an aligned run.
        const std::size_t size = rounded(bytes);
        void* m = mmap(nullptr, size + kHugePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (m == MAP_FAILED) throw std::bad_alloc();
        const auto start = reinterpret_cast<std::uintptr_t>(m);
        const auto begin = (start + kHugePage - 1) & ~(kHugePage - 1);
        if (begin > start) munmap(m, begin - start);
        if (begin - start < kHugePage) munmap(reinterpret_cast<void*>(begin + size), kHugePage - (begin - start));
        adviseHugePages(reinterpret_cast<void*>(begin), size);
        return reinterpret_cast<void*>(begin);
    }
#endif
    return ::operator new(bytes);
}

void freeHuge(void* p, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (bytes >= kHugeFrom) {
        munmap(p, rounded(bytes));
        return;
    }
#endif
    ::operator delete(p);
}

}  // namespace isohex::detail

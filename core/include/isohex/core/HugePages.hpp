#pragma once
// Large temporary buffers on 2 MiB pages.
//
// Fresh anonymous memory is mapped page by page on first write, and in a
// virtual machine each 4 KiB fault is dear (3 ms per MB on the bench machine,
// against 0.1 ms per MB for 2 MiB pages). HugeAlloc gives a large buffer whole
// 2 MiB pages of its own, aligned and advised for transparent huge pages, so
// it costs a few faults instead of one per 4 KiB, and unmaps them when it goes
// (its memory returns to the system at once, malloc's own thresholds are left
// alone). Small buffers come from operator new as usual. Only a hint: where
// the kernel does not honour it nothing changes but the speed.
#include <cstddef>
#include <vector>

#include "isohex/core/Csr.hpp"

namespace isohex {

namespace detail {
inline constexpr std::size_t kHugePage = std::size_t{1} << 21;
inline constexpr std::size_t kHugeFrom = std::size_t{1} << 20;  // bytes: smaller buffers use operator new
// Asks for transparent huge pages on the whole aligned 2 MiB pieces of [p, p + bytes).
void adviseHugePages(const void* p, std::size_t bytes);
// `bytes` (at least kHugeFrom) on whole aligned huge pages, or operator new
// where mapping them is not supported; freed with freeHuge(p, bytes).
void* allocateHuge(std::size_t bytes);
void freeHuge(void* p, std::size_t bytes);
}  // namespace detail

template <class T>
struct HugeAlloc {
    using value_type = T;
    HugeAlloc() = default;
    template <class U>
    HugeAlloc(const HugeAlloc<U>&) {}
    T* allocate(std::size_t n) { return static_cast<T*>(detail::allocateHuge(n * sizeof(T))); }
    void deallocate(T* p, std::size_t n) { detail::freeHuge(p, n * sizeof(T)); }
    template <class U>
    bool operator==(const HugeAlloc<U>&) const { return true; }
};

template <class T>
using BigVec = std::vector<T, HugeAlloc<T>>;

// Compressed rows in BigVecs.
using BigCsr = CsrOf<BigVec<Index>>;

// Room for n elements, with the part not yet written advised for huge pages
// (for vectors with the standard allocator that are about to grow large).
template <class T, class A>
void reserveHuge(std::vector<T, A>& v, std::size_t n) {
    if (v.capacity() < n) v.reserve(n);
    detail::adviseHugePages(v.data() + v.size(), (v.capacity() - v.size()) * sizeof(T));
}

// Gives a buffer's memory back at once (the large ones go back to the system).
template <class V>
void release(V& v) {
    V().swap(v);
}

}  // namespace isohex

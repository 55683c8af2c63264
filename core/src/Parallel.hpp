#pragma once
// Small deterministic parallel building blocks shared by topology and dual code.
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/core/Topology.hpp"

namespace isohex::detail {

// Counting sort of items 0..items-1 into buckets (an O(n) CSR build). Rows are
// sorted by item id afterwards, so the result does not depend on the thread
// count even though items are scattered with atomics.
template <class BucketOf>
Csr bucketItems(std::size_t buckets, std::size_t items, BucketOf bucketOf) {
    Csr c;
    c.offsets.assign(buckets + 1, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, items, 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i)
            std::atomic_ref<Index>(c.offsets[static_cast<std::size_t>(bucketOf(i)) + 1])
                .fetch_add(1, std::memory_order_relaxed);
    });
    for (std::size_t b = 0; b < buckets; ++b) c.offsets[b + 1] += c.offsets[b];
    std::vector<Index> cursor(c.offsets.begin(), c.offsets.end() - 1);
    c.items.resize(items);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, items, 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const Index pos = std::atomic_ref<Index>(cursor[static_cast<std::size_t>(bucketOf(i))])
                                  .fetch_add(1, std::memory_order_relaxed);
            c.items[static_cast<std::size_t>(pos)] = static_cast<Index>(i);
        }
    });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, buckets, 1024), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b)
            std::sort(c.items.begin() + c.offsets[b], c.items.begin() + c.offsets[b + 1]);
    });
    return c;
}

}  // namespace isohex::detail

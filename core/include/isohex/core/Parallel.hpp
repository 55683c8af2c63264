#pragma once
// Deterministic parallel building blocks: each gives the same result for any
// thread count (rows and kept positions in a fixed order, partial results
// combined in a fixed order), so meshes do not depend on the machine.
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include "isohex/core/Csr.hpp"
#include "isohex/core/HugePages.hpp"

namespace isohex::parallel {

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

// Positions i in [0, n) where flag(i) holds, in increasing order, found in
// parallel over fixed blocks (so the same for any thread count); flag is
// evaluated once per position, onCount(kept) is called once the number kept
// is known, then onKept(i, rank) for each kept one.
template <class Flag, class OnCount, class OnKept>
BigVec<Index> keepWhere(std::size_t n, Flag flag, OnCount onCount, OnKept onKept) {
    constexpr std::size_t B = std::size_t{1} << 14;
    const std::size_t blocks = (n + B - 1) / B;
    BigVec<std::uint8_t> f(n);
    std::vector<Index> count(blocks + 1, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index k = 0;
            for (std::size_t i = b * B, e = std::min(n, i + B); i < e; ++i) k += f[i] = flag(i) ? 1 : 0;
            count[b + 1] = k;
        }
    });
    for (std::size_t b = 0; b < blocks; ++b) count[b + 1] += count[b];
    onCount(static_cast<std::size_t>(count[blocks]));
    BigVec<Index> out(static_cast<std::size_t>(count[blocks]));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks, 1), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index k = count[b];
            for (std::size_t i = b * B, e = std::min(n, i + B); i < e; ++i)
                if (f[i]) {
                    out[static_cast<std::size_t>(k)] = static_cast<Index>(i);
                    onKept(i, k++);
                }
        }
    });
    return out;
}

template <class Flag>
BigVec<Index> keepWhere(std::size_t n, Flag flag) {
    return keepWhere(n, flag, [](std::size_t) {}, [](std::size_t, Index) {});
}

// Rows 0..rows-1 of the pairs (row, item) that forEachIn(lo, hi, emit)
// produces for the elements lo..hi-1 of [0, n), in the order it produces
// them (so rows come out sorted when items are produced in increasing order).
// A counting sort over a few contiguous blocks of [0, n), in parallel: each
// block counts its own, then writes after the blocks before it, so the rows
// are those of one serial pass for any number of blocks.
template <class ForEachIn>
BigCsr rowsInOrder(std::size_t rows, std::size_t n, ForEachIn forEachIn) {
    const std::size_t P = std::clamp<std::size_t>(static_cast<std::size_t>(tbb::this_task_arena::max_concurrency()), 1, 4);
    BigVec<Index> at(P * rows, 0);  // per block and row: its count, then where it writes
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, P, 1), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index* count = at.data() + b * rows;
            forEachIn(n * b / P, n * (b + 1) / P, [&](Index row, Index) { ++count[static_cast<std::size_t>(row)]; });
        }
    });
    BigCsr c;
    c.offsets.resize(rows + 1);
    Index next = 0;
    for (std::size_t row = 0; row < rows; ++row) {
        c.offsets[row] = next;
        for (std::size_t b = 0; b < P; ++b) {
            const Index k = at[b * rows + row];
            at[b * rows + row] = next;
            next += k;
        }
    }
    c.offsets[rows] = next;
    c.items.resize(static_cast<std::size_t>(next));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, P, 1), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index* cursor = at.data() + b * rows;
            forEachIn(n * b / P, n * (b + 1) / P, [&](Index row, Index item) {
                c.items[static_cast<std::size_t>(cursor[static_cast<std::size_t>(row)]++)] = item;
            });
        }
    });
    return c;
}

// Folds [0, n) in fixed blocks of `block` positions in parallel
// (fold(acc, i) for each position of a block into a fresh Acc), then adds the
// blocks' results in block order with combine(total, part): the same result
// for any thread count, floating-point sums included.
template <class Acc, class Fold, class Combine>
Acc blockReduce(std::size_t n, std::size_t block, Fold fold, Combine combine) {
    const std::size_t blocks = (n + block - 1) / block;
    std::vector<Acc> part(blocks);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Acc a{};
            for (std::size_t i = b * block, e = std::min(n, i + block); i < e; ++i) fold(a, i);
            part[b] = a;
        }
    });
    Acc total{};
    for (const Acc& a : part) combine(total, a);
    return total;
}

// The items visit(r, out) appends to `out` for the subranges r of [0, n), in
// parallel (each thread into its own list), gathered and sorted: the same
// list for any thread count.
template <class T, class Visit>
std::vector<T> collectSorted(std::size_t n, std::size_t grain, Visit visit) {
    tbb::enumerable_thread_specific<std::vector<T>> local;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const auto& r) { visit(r, local.local()); });
    std::vector<T> all;
    for (auto& l : local) all.insert(all.end(), l.begin(), l.end());
    std::sort(all.begin(), all.end());
    return all;
}

// tbb::parallel_reduce over [0, n) with an accumulator that has merge();
// `visit` gets a whole subrange so it can keep scratch buffers across
// iterations. Only for accumulators whose merge gives the same result in any
// grouping (counts, smallest ids, sets): the grouping depends on the threads.
template <class Acc, class Visit>
Acc reduceOver(std::size_t n, std::size_t grain, Visit visit) {
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, n, grain), Acc{},
        [&](const tbb::blocked_range<std::size_t>& r, Acc acc) {
            visit(r, acc);
            return acc;
        },
        [](Acc a, const Acc& b) {
            a.merge(b);
            return a;
        });
}

}  // namespace isohex::parallel

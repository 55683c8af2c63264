#pragma once
// Disjoint sets (union-find) over the indices 0..n-1: the one implementation
// every module uses (component labelling of grids, meshes and surfaces, fans
// around a node, sheets and chords of the dual, repair regions).
//
// The representative (root) of a set is always its smallest member: unite()
// links the larger root under the smaller one. Callers rely on this for
// deterministic labelling (numbering classes by their root in index order, the
// tie "smallest root" when picking one set, first-seen order of roots), so the
// result depends only on the partition, never on the order of the unions or on
// the thread count. It also keeps parent(a) <= a for every a, so the sets of
// the first n indices never refer past n (see truncate()).
//
// find() uses path halving (every node on the path is linked to its
// grandparent): near-constant amortised time without recursion or a second
// pass. Union by rank/size is deliberately absent: it would break the
// smallest-root rule.
//
// Storage is std::vector<I> by default (growable: reset(n), add(), truncate())
// or a fixed std::array<I, N> for small local problems that must not touch
// the heap (FixedDisjointSets<I, N>). I is the index type: a narrow one
// (std::int16_t) keeps small fixed tables compact, a wide one (std::size_t)
// serves grids of any size. Everything is inline and non-virtual; no call
// allocates except reset(n)/add() growing a vector past its capacity.
#include <array>
#include <cstddef>
#include <type_traits>
#include <vector>

namespace isohex {

template <class I, class Storage = std::vector<I>>
class DisjointSets {
    static_assert(std::is_integral_v<I>, "DisjointSets: integral index type expected");
    static_assert(std::is_same_v<typename Storage::value_type, I>, "DisjointSets: storage of I expected");

public:
    using index_type = I;
    // Whether the storage can change size (std::vector) or is fixed (std::array).
    static constexpr bool kGrowable = requires(Storage s) { s.resize(std::size_t{0}); };

    // Growable: no elements. Fixed: all N elements as singletons.
    DisjointSets() {
        if constexpr (!kGrowable) reset();
    }
    // n singletons {0}, ..., {n-1}.
    explicit DisjointSets(std::size_t n)
        requires kGrowable
    {
        reset(n);
    }

    // Makes every current element a singleton again.
    void reset() {
        for (std::size_t i = 0; i < parent_.size(); ++i) parent_[i] = static_cast<I>(i);
    }
    // n singletons; a vector keeps its capacity, so reusing one object in a
    // loop allocates only when n exceeds every earlier n.
    void reset(std::size_t n)
        requires kGrowable
    {
        parent_.resize(n);
        reset();
    }

    // Adds the singleton {size()} and returns its index.
    I add()
        requires kGrowable
    {
        const I i = static_cast<I>(parent_.size());
        parent_.push_back(i);
        return i;
    }
    // Drops the elements n.. (undoing add()s); the sets of 0..n-1 are
    // unaffected as no element refers to a larger one. Unions made since
    // between two elements below n are kept.
    void truncate(std::size_t n)
        requires kGrowable
    {
        parent_.resize(n);
    }

    std::size_t size() const { return parent_.size(); }

    // The root (smallest member) of a's set, halving the path on the way.
    I find(I a) {
        while (parent_[a] != a) a = parent_[a] = parent_[parent_[a]];
        return a;
    }
    // Joins the sets of a and b (a found first, then b); returns the root of
    // the union, the smaller of the two roots.
    I unite(I a, I b) {
        a = find(a);
        b = find(b);
        if (a == b) return a;
        if (a < b) {
            parent_[b] = a;
            return a;
        }
        parent_[a] = b;
        return b;
    }
    bool same(I a, I b) { return find(a) == find(b); }
    // Whether a is the root of its set (no path compression needed: a root is
    // exactly an element that is its own parent).
    bool isRoot(I a) const { return parent_[a] == a; }
    // a's current parent (a itself for a root): for tests and invariants.
    I parentOf(I a) const { return parent_[a]; }
    // The number of sets (roots) among all elements.
    std::size_t countSets() const {
        std::size_t n = 0;
        for (std::size_t i = 0; i < parent_.size(); ++i) n += parent_[i] == static_cast<I>(i);
        return n;
    }

private:
    Storage parent_;  // parent_[a] <= a; a root is its own parent (std::array: filled by reset())
};

// Fixed-size disjoint sets of N elements on the stack (no heap allocation).
template <class I, std::size_t N>
using FixedDisjointSets = DisjointSets<I, std::array<I, N>>;

}  // namespace isohex

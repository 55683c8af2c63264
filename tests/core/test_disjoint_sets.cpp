// DisjointSets: the smallest member is the root, path halving, the count of
// sets, growth and truncation, the fixed-size variant; and the partition
// against a breadth-first search on random graphs, in several union orders.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <queue>
#include <random>
#include <utility>
#include <vector>

#include "isohex/core/DisjointSets.hpp"

using namespace isohex;

namespace {

using Edges = std::vector<std::pair<int, int>>;

// Per vertex: the smallest vertex of its connected component, by BFS.
std::vector<int> bfsSmallest(int n, const Edges& edges, int* components) {
    std::vector<std::vector<int>> adj(n);
    for (auto [a, b] : edges) {
        adj[a].push_back(b);
        adj[b].push_back(a);
    }
    std::vector<int> label(n, -1);
    *components = 0;
    for (int s = 0; s < n; ++s) {
        if (label[s] >= 0) continue;
        ++*components;
        // s is the smallest vertex of its component: every smaller one was labelled already
        std::queue<int> q;
        q.push(s);
        label[s] = s;
        while (!q.empty()) {
            const int v = q.front();
            q.pop();
            for (int w : adj[v])
                if (label[w] < 0) {
                    label[w] = s;
                    q.push(w);
                }
        }
    }
    return label;
}

Edges randomGraph(std::mt19937& rng, int n, int m) {
    std::uniform_int_distribution<int> pick(0, n - 1);
    Edges e;
    for (int i = 0; i < m; ++i) e.emplace_back(pick(rng), pick(rng));
    return e;
}

template <class Sets>
void expectMatchesBfs(Sets& sets, int n, const Edges& edges) {
    int components = 0;
    const std::vector<int> smallest = bfsSmallest(n, edges, &components);
    EXPECT_EQ(sets.countSets(), static_cast<std::size_t>(components));
    for (int v = 0; v < n; ++v) {
        using I = typename Sets::index_type;
        ASSERT_EQ(static_cast<int>(sets.find(static_cast<I>(v))), smallest[v]) << "vertex " << v;
        EXPECT_EQ(sets.isRoot(static_cast<I>(v)), smallest[v] == v);
        EXPECT_LE(static_cast<int>(sets.parentOf(static_cast<I>(v))), v);
    }
}

}  // namespace

TEST(DisjointSets, SingletonsAfterConstruction) {
    DisjointSets<int> s(5);
    EXPECT_EQ(s.size(), 5u);
    EXPECT_EQ(s.countSets(), 5u);
    for (int i = 0; i < 5; ++i) {
        EXPECT_EQ(s.find(i), i);
        EXPECT_TRUE(s.isRoot(i));
    }
    DisjointSets<int> empty;
    EXPECT_EQ(empty.size(), 0u);
    EXPECT_EQ(empty.countSets(), 0u);
}

TEST(DisjointSets, SmallestMemberIsRoot) {
    DisjointSets<int> s(8);
    EXPECT_EQ(s.unite(7, 5), 5);  // the larger root goes under the smaller whichever argument it is
    EXPECT_EQ(s.unite(2, 6), 2);
    EXPECT_EQ(s.unite(5, 6), 2);
    EXPECT_EQ(s.unite(7, 2), 2);  // already one set
    for (int v : {2, 5, 6, 7}) EXPECT_EQ(s.find(v), 2) << v;
    for (int v : {0, 1, 3, 4}) EXPECT_EQ(s.find(v), v) << v;
    EXPECT_TRUE(s.same(5, 6));
    EXPECT_FALSE(s.same(1, 6));
    EXPECT_EQ(s.countSets(), 5u);
    EXPECT_EQ(s.unite(6, 0), 0);
    for (int v : {0, 2, 5, 6, 7}) EXPECT_EQ(s.find(v), 0) << v;
    EXPECT_EQ(s.countSets(), 4u);
}

TEST(DisjointSets, PathHalving) {
    // the chain 4 -> 3 -> 2 -> 1 -> 0
    DisjointSets<int> s(5);
    s.unite(3, 4);
    s.unite(2, 3);
    s.unite(1, 2);
    s.unite(0, 1);
    for (int v = 1; v < 5; ++v) ASSERT_EQ(s.parentOf(v), v - 1);
    // halving links every other node on the path to its grandparent:
    // 4 -> 2 and 2 -> 0; 3 and 1 keep their parents (full compression would move 3)
    EXPECT_EQ(s.find(4), 0);
    EXPECT_EQ(s.parentOf(4), 2);
    EXPECT_EQ(s.parentOf(3), 2);
    EXPECT_EQ(s.parentOf(2), 0);
    EXPECT_EQ(s.parentOf(1), 0);
    EXPECT_EQ(s.find(4), 0);
    EXPECT_EQ(s.parentOf(4), 0);
    EXPECT_EQ(s.find(3), 0);
    EXPECT_EQ(s.parentOf(3), 0);
}

TEST(DisjointSets, ResetKeepsNothing) {
    DisjointSets<std::uint32_t> s(6);
    s.unite(1, 4);
    s.unite(4, 5);
    s.reset(4);
    EXPECT_EQ(s.size(), 4u);
    EXPECT_EQ(s.countSets(), 4u);
    s.unite(3, 2);
    s.reset(7);
    EXPECT_EQ(s.countSets(), 7u);
    for (std::uint32_t v = 0; v < 7; ++v) EXPECT_EQ(s.find(v), v);
}

TEST(DisjointSets, AddAndTruncate) {
    DisjointSets<std::int32_t> s(3);
    s.unite(0, 2);
    EXPECT_EQ(s.add(), 3);
    EXPECT_EQ(s.add(), 4);
    s.unite(4, 1);
    s.unite(3, 2);
    EXPECT_EQ(s.find(3), 0);
    EXPECT_EQ(s.find(4), 1);
    s.truncate(3);
    EXPECT_EQ(s.size(), 3u);
    EXPECT_EQ(s.find(2), 0);
    EXPECT_EQ(s.find(1), 1);
    EXPECT_EQ(s.countSets(), 2u);
    EXPECT_EQ(s.add(), 3);
    EXPECT_EQ(s.find(3), 3);  // a fresh singleton, nothing left of the old 3
}

TEST(DisjointSets, RandomGraphsAgainstBfs) {
    std::mt19937 rng(20261123);
    for (int round = 0; round < 200; ++round) {
        const int n = 1 + static_cast<int>(rng() % 300);
        const int m = static_cast<int>(rng() % (2 * n));
        Edges edges = randomGraph(rng, n, m);
        DisjointSets<int> a(static_cast<std::size_t>(n));
        for (auto [x, y] : edges) a.unite(x, y);
        expectMatchesBfs(a, n, edges);
        // the partition and the roots do not depend on the order of the unions
        std::shuffle(edges.begin(), edges.end(), rng);
        DisjointSets<std::size_t> b(static_cast<std::size_t>(n));
        for (auto [x, y] : edges) b.unite(static_cast<std::size_t>(y), static_cast<std::size_t>(x));
        expectMatchesBfs(b, n, edges);
        // interleaving finds (path halving) changes nothing either
        a.reset(static_cast<std::size_t>(n));
        for (auto [x, y] : edges) {
            a.unite(x, y);
            a.find(static_cast<int>(rng() % static_cast<unsigned>(n)));
        }
        expectMatchesBfs(a, n, edges);
    }
}

TEST(DisjointSets, FixedSizeInt16) {
    using Sets = FixedDisjointSets<std::int16_t, 864>;
    static_assert(sizeof(Sets) == 864 * sizeof(std::int16_t), "no heap storage, no extra members");
    static_assert(!Sets::kGrowable);
    std::mt19937 rng(7);
    for (int round = 0; round < 20; ++round) {
        Sets s;  // all 864 are singletons
        EXPECT_EQ(s.countSets(), 864u);
        const Edges edges = randomGraph(rng, 864, 600 + round * 20);
        for (auto [x, y] : edges) s.unite(static_cast<std::int16_t>(x), static_cast<std::int16_t>(y));
        expectMatchesBfs(s, 864, edges);
        s.reset();
        EXPECT_EQ(s.countSets(), 864u);
    }
}

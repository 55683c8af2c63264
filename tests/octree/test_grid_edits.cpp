// Grid edits: keeping the largest regions, filling pits, edits near inverted hexes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <set>

#include "AnalyticDomains.hpp"
#include "LabelGrids.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/octree/DualContour.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/GridEdits.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/Regions.hpp"

using namespace isohex;
using namespace isohex::octree;
using namespace isohex::test;

TEST(KeepLargest, DropsSmallerRegionsOfEachMaterialOnly) {
    const AnalyticDomain d({unite(sphere({8, 10, 10}, 5), sphere({17, 10, 10}, 2.2)), sphere({10, 10, 25}, 3)});
    octree::Grid g = unitGrid(31);
    Labels l = sampleLabels(d, g);
    std::size_t small = 0, second = 0;
    for (std::size_t p = 0; p < l.material.size(); ++p) {
        const int i = static_cast<int>(p % 31);
        small += l.material[p] == 1 && i > 14;
        second += l.material[p] == 2;
    }
    ASSERT_GT(small, 0u);
    const std::size_t removed = keepLargestComponents(l);
    EXPECT_EQ(removed, small);
    std::size_t secondAfter = 0;
    for (auto m : l.material) secondAfter += m == 2;
    EXPECT_EQ(secondAfter, second);  // material 2 is one region: untouched
    const auto topo = regionTopology(l);
    ASSERT_EQ(topo.size(), 2u);
    EXPECT_EQ(topo[0].components, 1u);
}

TEST(FillPits, FillsOneCellPitsAndWellsButKeepsCavitiesAndWiderGaps) {
    const int n = 12;
    auto v = solidBlock(n, 2, 9);
    set(v, n, 5, 5, 9, 0);                                           // a pit one cell deep, open at the top
    for (int k = 7; k <= 9; ++k) set(v, n, 3, 3, k, 0);              // a well three cells deep
    set(v, n, 7, 4, 5, 0);                                           // a one-point cavity
    set(v, n, 4, 7, 4, 0), set(v, n, 4, 7, 5, 0);                    // a two-point cavity
    set(v, n, 7, 7, 9, 0), set(v, n, 8, 7, 9, 0);                    // a trench two cells wide
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    const auto before = regionTopology(l);
    const std::size_t filled = fillOneCellPits(l);
    auto at = [&](int i, int j, int k) { return l.material[l.grid.index(i, j, k)]; };
    EXPECT_EQ(filled, 4u);
    EXPECT_EQ(at(5, 5, 9), 1);
    for (int k = 7; k <= 9; ++k) EXPECT_EQ(at(3, 3, k), 1) << k;
    EXPECT_EQ(at(7, 4, 5), 0);
    EXPECT_EQ(at(4, 7, 4), 0);
    EXPECT_EQ(at(4, 7, 5), 0);
    EXPECT_EQ(at(7, 7, 9), 0);
    EXPECT_EQ(at(8, 7, 9), 0);
    EXPECT_EQ(at(5, 5, 10), 0);  // nothing grows above the rim
    // simple points only: components and Euler characteristic (with both cavities) unchanged
    const auto after = regionTopology(l);
    ASSERT_EQ(before.size(), 1u);
    ASSERT_EQ(after.size(), 1u);
    EXPECT_EQ(after[0].components, before[0].components);
    EXPECT_EQ(after[0].euler, before[0].euler);
    EXPECT_EQ(after[0].points, before[0].points + 4);
    EXPECT_EQ(before[0].components, 3u);  // the outer surface and the two cavities
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d)));
    EXPECT_EQ(fillOneCellPits(l), 0u);  // a fixpoint
}

// editNearInvertedHexes (the pipeline's retry where hexes stay inverted):
// near the given positions it shaves a one-point bump and fills a one-point
// pit, moves a material's lone point into the material around it, and never
// edits a point whose change would alter a topology (a bridge, a speck, a
// cavity), a frozen point, or twice at one place.
TEST(InvertedHexEdits, ShavesABumpFillsAPitAndNeverChangesTopology) {
    const int n = 14;
    auto v = solidBlock(n, 2, 10);
    set(v, n, 6, 6, 11, 1);   // a one-point bump on the top face
    set(v, n, 4, 4, 10, 0);   // a one-point pit in it
    set(v, n, 8, 8, 6, 0);    // a one-point cavity inside
    const PointSetDomain d({n, n, n}, v);
    const Labels start = sampleLabels(d, unitGrid(n));
    ASSERT_EQ(countNonManifoldBlocks(start), 0u);
    const auto before = regionTopology(start);
    auto at = [](const Labels& l, int i, int j, int k) { return l.material[l.grid.index(i, j, k)]; };

    Labels l = start;
    // two positions at the bump (one edit there), one at the pit, one at the cavity
    const auto edits = editNearInvertedHexes(l, {{6.2, 5.9, 11.3}, {6.0, 6.4, 11.0}, {4.3, 4.1, 9.8}, {8, 8, 6}});
    ASSERT_EQ(edits.size(), 2u);
    EXPECT_EQ(edits[0].point, l.grid.index(6, 6, 11));
    EXPECT_EQ(edits[0].from, 1);
    EXPECT_EQ(edits[0].to, 0);
    EXPECT_EQ(edits[1].point, l.grid.index(4, 4, 10));
    EXPECT_EQ(edits[1].from, 0);
    EXPECT_EQ(edits[1].to, 1);
    EXPECT_EQ(at(l, 6, 6, 11), 0);
    EXPECT_EQ(at(l, 4, 4, 10), 1);
    EXPECT_EQ(at(l, 8, 8, 6), 0);  // filling the cavity would remove a boundary component
    const auto after = regionTopology(l);
    ASSERT_EQ(after.size(), 1u);
    EXPECT_EQ(after[0].components, before[0].components);
    EXPECT_EQ(after[0].euler, before[0].euler);
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);

    // frozen: the bump stays, and nothing else near it is exposed enough
    Labels f = start;
    EXPECT_TRUE(editNearInvertedHexes(f, {{6, 6, 11}}, {f.grid.index(6, 6, 11)}).empty());
    EXPECT_EQ(f.material, start.material);

    // a bridge one point thick between two blocks, and a lone speck: no edit
    auto w = grid3(n);
    for (int k = 2; k <= 10; ++k)
        for (int j = 2; j <= 10; ++j)
            for (int i : {2, 3, 4, 8, 9, 10}) set(w, n, i, j, k);
    for (int i = 5; i <= 7; ++i) set(w, n, i, 6, 6);  // the bridge
    set(w, n, 6, 11, 11);                              // a speck
    const PointSetDomain d2({n, n, n}, w);
    Labels b = sampleLabels(d2, unitGrid(n));
    const Labels bridge = b;
    EXPECT_TRUE(editNearInvertedHexes(b, {{6, 6, 6}, {6, 11, 11}}).empty());
    EXPECT_EQ(b.material, bridge.material);
    // the maximum of own-material face neighbours bounds what counts as exposed
    EXPECT_TRUE(editNearInvertedHexes(l = start, {{6, 6, 11}}, {}, 0).empty());
}

TEST(InvertedHexEdits, AMaterialsLonePointJoinsTheMaterialAroundIt) {
    // materials 1 (x 2..6) and 2 (x 7..11); one point of 2 sticks into 1
    const int n = 14;
    auto v = grid3(n);
    for (int k = 2; k <= 10; ++k)
        for (int j = 2; j <= 10; ++j)
            for (int i = 2; i <= 11; ++i) set(v, n, i, j, k, i <= 6 ? 1 : 2);
    set(v, n, 6, 6, 6, 2);
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    const auto before = regionTopology(l);
    const auto edits = editNearInvertedHexes(l, {{6.4, 6, 6}});
    ASSERT_EQ(edits.size(), 1u);
    EXPECT_EQ(edits[0].point, l.grid.index(6, 6, 6));
    EXPECT_EQ(edits[0].from, 2);
    EXPECT_EQ(edits[0].to, 1);
    const auto after = regionTopology(l);
    ASSERT_EQ(after.size(), before.size());
    for (std::size_t m = 0; m < after.size(); ++m) {
        EXPECT_EQ(after[m].components, before[m].components);
        EXPECT_EQ(after[m].euler, before[m].euler);
    }
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);

    // a one-point pocket of background where the two meet: filling it with
    // material 1 keeps material 1's topology (it only touches 1 and 2), but
    // the object's union would lose a cavity, so it stays
    set(v, n, 6, 6, 6, 0);
    const PointSetDomain d2({n, n, n}, v);
    Labels pocket = sampleLabels(d2, unitGrid(n));
    const Labels pocketStart = pocket;
    EXPECT_TRUE(editNearInvertedHexes(pocket, {{6, 6, 6}}).empty());
    EXPECT_EQ(pocket.material, pocketStart.material);
    // positions off the grid or not finite are skipped
    EXPECT_TRUE(editNearInvertedHexes(pocket, {{-5, 6, 6}, {6, 1e300, 6}, {std::nan(""), 6, 6}}).empty());
}

TEST(InvertedHexEdits, RandomLabelsKeepTheirTopologyAndStayManifold) {
    // Blobby random labellings with up to three materials, repaired, then
    // edited at random positions: whatever is edited, every material keeps its
    // components and Euler characteristic, every block stays manifold, every
    // edit lies within one point of a position and had at most two face
    // neighbours of its material, and the mesh extracts valid.
    std::size_t total = 0;
    for (unsigned seed = 1; seed <= 60; ++seed) {
        const int n = 12;
        auto v = grid3(n);
        unsigned state = seed * 2654435761u;
        auto rnd = [&] { return (state = state * 1664525u + 1013904223u) >> 8; };
        const int balls = 3 + static_cast<int>(rnd() % 4);
        std::vector<std::array<double, 5>> c;  // centre, radius, material
        for (int b = 0; b < balls; ++b)
            c.push_back({2.0 + rnd() % 800 / 100.0, 2.0 + rnd() % 800 / 100.0, 2.0 + rnd() % 800 / 100.0,
                         1.0 + rnd() % 250 / 100.0, static_cast<double>(1 + rnd() % (seed % 3 + 1))});
        for (int k = 1; k < n - 1; ++k)
            for (int j = 1; j < n - 1; ++j)
                for (int i = 1; i < n - 1; ++i)
                    for (const auto& b : c)
                        if ((i - b[0]) * (i - b[0]) + (j - b[1]) * (j - b[1]) + (k - b[2]) * (k - b[2]) <= b[3] * b[3])
                            set(v, n, i, j, k, static_cast<std::int32_t>(b[4]));
        const PointSetDomain d({n, n, n}, v);
        Labels l = sampleLabels(d, unitGrid(n));
        repairNonManifold(l, d);
        ASSERT_EQ(countNonManifoldBlocks(l), 0u) << "seed " << seed;
        const Labels start = l;
        const auto before = regionTopology(l);
        auto unionOf = [](Labels u) {
            for (auto& m : u.material) m = m != 0 ? 1 : 0;
            return regionTopology(u);
        };
        const auto unionBefore = unionOf(l);
        std::vector<std::array<double, 3>> at;
        for (int q = 0; q < 12; ++q)
            at.push_back({1.0 + rnd() % 1000 / 100.0, 1.0 + rnd() % 1000 / 100.0, 1.0 + rnd() % 1000 / 100.0});
        const auto edits = editNearInvertedHexes(l, at);
        total += edits.size();
        Labels cur = start;  // the labels as each edit found them (earlier edits of the call applied)
        for (const auto& e : edits) {
            const int i = static_cast<int>(e.point % n), j = static_cast<int>(e.point / n % n),
                      k = static_cast<int>(e.point / n / n);
            EXPECT_EQ(cur.material[e.point], e.from);
            EXPECT_NE(e.from, e.to);
            EXPECT_TRUE(std::any_of(at.begin(), at.end(), [&](const auto& x) {
                return std::abs(std::lround(x[0]) - i) <= 1 && std::abs(std::lround(x[1]) - j) <= 1 &&
                       std::abs(std::lround(x[2]) - k) <= 1;
            })) << "seed " << seed;
            int same = 0;
            for (int a = 0; a < 3; ++a)
                for (int s : {-1, 1}) {
                    std::array<int, 3> q{i, j, k};
                    q[a] += s;
                    same += cur.material[cur.grid.index(q[0], q[1], q[2])] == e.from;
                }
            EXPECT_LE(same, 2) << "seed " << seed;
            cur.material[e.point] = e.to;
        }
        EXPECT_EQ(cur.material, l.material) << "seed " << seed;
        std::size_t changed = 0;
        for (std::size_t p = 0; p < l.material.size(); ++p) changed += l.material[p] != start.material[p];
        EXPECT_EQ(changed, edits.size()) << "seed " << seed;
        EXPECT_EQ(countNonManifoldBlocks(l), 0u) << "seed " << seed;
        const auto after = regionTopology(l);
        ASSERT_EQ(after.size(), before.size()) << "seed " << seed;
        for (std::size_t m = 0; m < after.size(); ++m) {
            EXPECT_EQ(after[m].material, before[m].material) << "seed " << seed;
            EXPECT_EQ(after[m].components, before[m].components) << "seed " << seed << " material " << after[m].material;
            EXPECT_EQ(after[m].euler, before[m].euler) << "seed " << seed << " material " << after[m].material;
        }
        // the object as a whole (and so the background) keeps its topology too
        const auto unionAfter = unionOf(l);
        ASSERT_EQ(unionAfter.size(), unionBefore.size()) << "seed " << seed;
        if (!unionAfter.empty()) {
            EXPECT_EQ(unionAfter[0].components, unionBefore[0].components) << "seed " << seed;
            EXPECT_EQ(unionAfter[0].euler, unionBefore[0].euler) << "seed " << seed;
        }
        EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d))) << "seed " << seed;
    }
    std::cout << "[figures] " << total << " edits over 60 random labellings\n";
    EXPECT_GT(total, 60u);  // the check above is not vacuous
}

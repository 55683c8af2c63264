// Non-manifold repair of labelled grids.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <set>

#include "AnalyticDomains.hpp"
#include "LabelGrids.hpp"
#include "isohex/octree/DualContour.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/Regions.hpp"

using namespace isohex;
using namespace isohex::octree;
using namespace isohex::test;

TEST(NonManifoldRepair, TwoCubesSharingAnEdge) {
    const int n = 6;
    auto v = grid3(n);
    set(v, n, 2, 2, 2);
    set(v, n, 3, 3, 2);  // diagonal neighbour in a plane: touches along an edge
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    EXPECT_GT(countNonManifoldBlocks(l), 0u);
    const RepairReport r = repairNonManifold(l, d);
    EXPECT_GT(r.nonManifoldBefore, 0u);
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d)));
}

TEST(NonManifoldRepair, PocketsTouchingAlongAnEdgeStayTwoPockets) {
    // Two one-point pockets of the outside inside a solid block, touching
    // along an edge: marching cubes draws two little spheres. Filling one or
    // joining them would lose one; the repair moves a pocket by a point.
    const int n = 12;
    auto v = solidBlock(n, 2, 9);
    set(v, n, 5, 5, 5, 0);
    set(v, n, 6, 6, 5, 0);
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    EXPECT_GT(countNonManifoldBlocks(l), 0u);
    repairNonManifold(l, d);
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    const auto t = regionTopology(l);
    ASSERT_EQ(t.size(), 1u);
    EXPECT_EQ(t[0].components, 3u);  // the block's outside and two pockets
    EXPECT_EQ(t[0].euler, 6);
    EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d)));
}

TEST(NonManifoldRepair, SpeckKeptApartWhereTheRegionsSaySo) {
    // A one-point speck touching a block along an edge: one region unless the
    // caller's regions (e.g. volumeToMesh's parts) keep it apart, in which
    // case it stays a speck (the block gives up the points it touches, or
    // the speck moves by a point).
    const int n = 10;
    auto v = grid3(n);
    for (int k = 2; k <= 6; ++k)
        for (int j = 2; j <= 6; ++j)
            for (int i = 2; i <= 6; ++i) set(v, n, i, j, k);
    set(v, n, 7, 7, 4);
    const PointSetDomain d({n, n, n}, v);
    Labels joined = sampleLabels(d, unitGrid(n));
    repairNonManifold(joined, d);
    EXPECT_EQ(countNonManifoldBlocks(joined), 0u);
    EXPECT_EQ(regionTopology(joined)[0].components, 1u);
    Labels apart = sampleLabels(d, unitGrid(n));
    std::vector<std::int32_t> regions(apart.material.size(), 0);
    regions[apart.grid.index(7, 7, 4)] = 1;
    repairNonManifold(apart, d, &regions);
    EXPECT_EQ(countNonManifoldBlocks(apart), 0u);
    const auto t = regionTopology(apart);
    EXPECT_EQ(t[0].components, 2u);
    EXPECT_EQ(t[0].euler, 4);
    EXPECT_TRUE(topologicallyValid(dualContourHexes(apart, d)));
}

TEST(NonManifoldRepair, TwoCubesSharingAVertex) {
    const int n = 6;
    auto v = grid3(n);
    set(v, n, 2, 2, 2);
    set(v, n, 3, 3, 3);
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    EXPECT_GT(countNonManifoldBlocks(l), 0u);
    repairNonManifold(l, d);
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d)));
}

TEST(NonManifoldRepair, CheckerboardIsRepaired) {
    const int n = 8;
    auto v = grid3(n);
    for (int k = 1; k < n - 1; ++k)
        for (int j = 1; j < n - 1; ++j)
            for (int i = 1; i < n - 1; ++i)
                if ((i + j + k) % 2 == 0) set(v, n, i, j, k);
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    EXPECT_GT(countNonManifoldBlocks(l), 10u);
    repairNonManifold(l, d);
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    const HexMesh m = dualContourHexes(l, d);
    EXPECT_TRUE(topologicallyValid(m));
}

TEST(NonManifoldRepair, OneVoxelThinSheetIsManifoldAlready) {
    const int n = 8;
    auto v = grid3(n);
    for (int j = 2; j < 6; ++j)
        for (int i = 2; i < 6; ++i) set(v, n, i, j, 4);
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    const HexMesh m = dualContourHexes(l, d);
    EXPECT_EQ(m.hexCount(), 16u);
    EXPECT_TRUE(topologicallyValid(m));
}

TEST(NonManifoldRepair, RandomMultiMaterialLabelsBecomeValidMeshes) {
    // Random labellings are the worst case for touching regions: every material
    // and every interface between two materials must come out 2-manifold.
    for (unsigned seed = 1; seed <= 6; ++seed) {
        const int n = 9;
        auto v = grid3(n);
        unsigned state = seed * 2654435761u;
        for (int k = 1; k < n - 1; ++k)
            for (int j = 1; j < n - 1; ++j)
                for (int i = 1; i < n - 1; ++i) {
                    state = state * 1664525u + 1013904223u;
                    set(v, n, i, j, k, static_cast<std::int32_t>((state >> 16) % 4));  // 0..3
                }
        const PointSetDomain d({n, n, n}, v);
        Labels l = sampleLabels(d, unitGrid(n));
        repairNonManifold(l, d);
        EXPECT_EQ(countNonManifoldBlocks(l), 0u) << "seed " << seed;
        EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d))) << "seed " << seed;
    }
}

// Connected regions of grid points.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "AnalyticDomains.hpp"
#include "LabelGrids.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/Regions.hpp"

using namespace isohex;
using namespace isohex::octree;
using namespace isohex::test;

namespace {

Labels labelsOf(std::vector<std::int32_t> material, int n) {
    Labels l;
    l.grid = unitGrid(n);
    l.material = std::move(material);
    return l;
}

}  // namespace

TEST(Regions, FaceAdjacencyJoinsAlongFacesOnlyAndFullAlsoAtEdgesAndCorners) {
    const int n = 6;
    auto v = grid3(n);
    set(v, n, 1, 1, 1);  // a point
    set(v, n, 2, 1, 1);  // its face neighbour
    set(v, n, 3, 2, 1);  // touching (2,1,1) along an edge
    set(v, n, 4, 3, 2);  // touching (3,2,1) at a corner
    set(v, n, 4, 4, 4, 2);  // another material, alone
    set(v, n, 4, 4, 3, 1);  // material 1 next to it: not joined to it
    const Labels l = labelsOf(v, n);
    const Grid& g = l.grid;
    auto root = [&](DisjointSets<std::uint32_t>& s, int i, int j, int k) {
        return s.find(static_cast<std::uint32_t>(g.index(i, j, k)));
    };
    auto face = materialRegions(l, Adjacency::Face);
    EXPECT_EQ(root(face, 2, 1, 1), root(face, 1, 1, 1));
    EXPECT_EQ(root(face, 1, 1, 1), g.index(1, 1, 1));  // the root is the smallest point
    EXPECT_NE(root(face, 3, 2, 1), root(face, 1, 1, 1));
    EXPECT_NE(root(face, 4, 3, 2), root(face, 3, 2, 1));
    EXPECT_NE(root(face, 4, 4, 3), root(face, 4, 4, 4));
    auto full = materialRegions(l, Adjacency::Full);
    EXPECT_EQ(root(full, 3, 2, 1), g.index(1, 1, 1));
    EXPECT_EQ(root(full, 4, 3, 2), g.index(1, 1, 1));
    EXPECT_NE(root(full, 4, 4, 3), root(full, 4, 4, 4));  // other material
    EXPECT_EQ(root(full, 4, 4, 3), g.index(1, 1, 1));     // along an edge of (4,3,2)
    // background points stay alone
    EXPECT_EQ(root(full, 0, 0, 0), g.index(0, 0, 0));
    EXPECT_EQ(root(full, 5, 5, 5), g.index(5, 5, 5));
}

TEST(Regions, TopologyOfATorusAndTwoBalls) {
    const AnalyticDomain d({unite(sphere({6, 10, 10}, 3), sphere({14, 10, 10}, 3)), torus({20, 26, 26}, 5, 2)});
    const Labels l = sampleLabels(d, unitGrid(40));
    const auto topo = regionTopology(l);
    ASSERT_EQ(topo.size(), 2u);
    EXPECT_EQ(topo[0].material, 1);
    EXPECT_EQ(topo[0].components, 2u);
    EXPECT_EQ(topo[0].euler, 4);
    EXPECT_EQ(topo[1].material, 2);
    EXPECT_EQ(topo[1].components, 1u);
    EXPECT_EQ(topo[1].euler, 0);
    EXPECT_EQ(describe(topo),
              "material 1: 2 surface components, Euler characteristic 4; material 2: 1 surface component, Euler "
              "characteristic 0");
}

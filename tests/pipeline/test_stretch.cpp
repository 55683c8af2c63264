// The second max-min target: when it applies (stretchTargetFor) and what
// stretchWorstHexes keeps, on small blocks whose worst hexes are known.
#include <gtest/gtest.h>

#include <algorithm>

#include "isohex/core/Quality.hpp"
#include "isohex/pipeline/MinQuality.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "support/Blocks.hpp"

namespace isohex::pipeline {
namespace {

double minScaledJacobian(const HexMesh& m) {
    const std::vector<double> sj = scaledJacobians(m);
    return *std::min_element(sj.begin(), sj.end());
}

TEST(Stretch, AppliesOnlyWhereNoTargetIsChosen) {
    const MeshSettings defaults;
    EXPECT_EQ(stretchTargetFor("scan.nii.gz", defaults), kStretchTarget);
    EXPECT_EQ(stretchTargetFor("surface.off", defaults), 0.0);  // its target is 0.5 already
    MeshSettings s = defaults;
    s.worstHexTarget = 0.3;
    EXPECT_EQ(stretchTargetFor("scan.nii.gz", s), 0.0);
    s = defaults;
    s.minQuality = 0.1;
    EXPECT_EQ(stretchTargetFor("scan.nii.gz", s), 0.0);
    s = defaults;
    s.fixBoundary = true;
    EXPECT_EQ(stretchTargetFor("scan.nii.gz", s), 0.0);
    s = defaults;
    s.method = Method::Sheets;
    EXPECT_EQ(stretchTargetFor("surface.off", s), 0.0);
}

// A 3^3 block with its interior nodes pushed off their places: the hexes
// are between 0.3 and 0.5, the interior nodes can lift them, so the pass is
// kept and the minimum rises.
TEST(Stretch, KeptWhereItLiftsTheMinimum) {
    HexMesh m = test::makeBlock(3, 3, 3);
    m.nodes[21] = {1.3, 1.25, 0.75};  // node (1, 1, 1)
    m.nodes[42] = {2.25, 1.75, 2.3};  // node (2, 2, 2)
    const double before = minScaledJacobian(m);
    ASSERT_GE(before, 0.3);
    ASSERT_LT(before, 0.5);
    const StretchResult r = stretchWorstHexes(m, nullptr, kStretchTarget);
    EXPECT_TRUE(r.kept);
    EXPECT_DOUBLE_EQ(r.minBefore, before);
    EXPECT_GT(r.minAfter, before);
    EXPECT_DOUBLE_EQ(minScaledJacobian(m), r.minAfter);
    EXPECT_GE(r.meanAfter, r.meanBefore - kStretchMeanLoss);
}

// The worst hex's worst corner is made of boundary nodes only, which do not
// move without a projector: the pass moves the interior node for the other
// hexes but cannot lift the minimum, so every node goes back.
TEST(Stretch, PutsEveryNodeBackWhereTheMinimumCannotRise) {
    HexMesh m = test::makeBlock(2, 2, 2);
    m.nodes[0] = {0.25, 0.25, 0.25};  // corner 0 of hex 0: about 0.44
    m.nodes[13] = {1.2, 0.85, 1.15};  // the centre node
    const double before = minScaledJacobian(m);
    ASSERT_GE(before, 0.3);
    ASSERT_LT(before, 0.5);
    const std::vector<Vec3> start = m.nodes;
    const StretchResult r = stretchWorstHexes(m, nullptr, kStretchTarget);
    EXPECT_GT(r.pass.result.nodesMoved, 0u);
    EXPECT_FALSE(r.kept);
    EXPECT_EQ(m.nodes, start);
    EXPECT_DOUBLE_EQ(r.minAfter, before);
}

}  // namespace
}  // namespace isohex::pipeline

// Choosing the grid level: LBIE's cell tests and the topology-keeping level.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <set>

#include "AnalyticDomains.hpp"
#include "LabelGrids.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/LevelChoice.hpp"
#include "isohex/octree/Regions.hpp"

using namespace isohex;
using namespace isohex::octree;
using namespace isohex::test;

TEST(ChooseLevel, CoarsensASphereButNotBeyondItsTopology) {
    const AnalyticDomain d({sphere({32, 32, 32}, 20)});
    const LevelChoice c = chooseLevel(d, unitGrid(65));
    EXPECT_GE(c.level, 1);
    ASSERT_EQ(c.topology.size(), 1u);
    EXPECT_EQ(c.topology[0].euler, 2);
    EXPECT_LE(c.volumeChange, 0.05);
}

TEST(ChooseLevel, ThinTorusForcesAFinerLevelThanAFatOne) {
    const AnalyticDomain thin({torus({32, 32, 32}, 18, 2.2)});
    const AnalyticDomain fat({torus({32, 32, 32}, 18, 9)});
    const LevelChoice a = chooseLevel(thin, unitGrid(65));
    const LevelChoice b = chooseLevel(fat, unitGrid(65));
    EXPECT_LT(a.level, b.level);
    EXPECT_EQ(a.topology[0].euler, 0);
    EXPECT_EQ(b.topology[0].euler, 0);
}

TEST(LbieCellTests, SmoothLargeShapePassesAndThinFeatureFails) {
    // a big ball: coarse cells see at most one crossing per edge
    const AnalyticDomain ball({sphere({16, 16, 16}, 11)});
    EXPECT_EQ(lbieFailures(sampleLabels(ball, unitGrid(33))), 0u);
    // a plate one fine step thick between coarse points: coarse edges across it change material twice
    const AnalyticDomain plate({box({3, 3, 14.6}, {29, 29, 15.4})});
    EXPECT_GT(lbieFailures(sampleLabels(plate, unitGrid(33))), 0u);
}

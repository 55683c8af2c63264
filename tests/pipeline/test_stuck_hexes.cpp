// What the retries and the warnings count as stuck (StuckHexes.hpp): a hex
// inverted, or valid and below the floor; a perfect cube is neither, at any
// scale (a cube's scaled Jacobian can come out as 1 plus a rounding error).
#include <gtest/gtest.h>

#include "isohex/core/Quality.hpp"
#include "isohex/pipeline/StuckHexes.hpp"
#include "support/Blocks.hpp"

namespace isohex::pipeline {
namespace {

TEST(StuckHexes, PerfectCubesAreNeitherFlatNorDegenerateAtAnyScale) {
    // femur.off is in metres: its 12.7 mm cubes gave a scaled Jacobian just
    // above 1, which the count took for a collapsed hex (warned as "nearly
    // flat, lowest 0" on every femur mesh).
    for (const double h : {1.0, 0.5, 0.0127340934, 1e-4, 3.3e-3, 7.1}) {
        const HexMesh m = test::makeBlock(4, 3, 5, h, {0.0764045, -0.0700375, -0.45206});
        std::size_t aboveOne = 0;
        for (double sj : scaledJacobians(m)) {
            aboveOne += sj > 1.0;
            EXPECT_FALSE(scaledJacobianCollapsed(sj)) << "h " << h << ": " << sj;
        }
        const Stuck s = stuckHexes(m, 0.05);
        EXPECT_TRUE(s.flat.empty()) << "h " << h << ": " << s.flat.size() << " flat (" << aboveOne
                                    << " cubes with a scaled Jacobian above 1)";
        EXPECT_TRUE(s.inverted.empty());
        EXPECT_GT(s.minValid, 0.999) << "h " << h;
    }
}

TEST(StuckHexes, ACollapsedHexIsFlatWithValueZero) {
    HexMesh m = test::makeBlock(1, 1, 1, 1.0);
    // squash the first hex's top face onto its bottom: every vertical edge of
    // it has length 0, which scaledJacobian marks as collapsed
    const Hex& h = m.hexes[0];
    for (int c = 4; c < 8; ++c) m.nodes[static_cast<std::size_t>(h[c])] = m.nodes[static_cast<std::size_t>(h[c - 4])];
    EXPECT_TRUE(scaledJacobianCollapsed(scaledJacobians(m)[0]));
    const Stuck s = stuckHexes(m, 0.05);
    ASSERT_EQ(s.flat.size() + s.inverted.size(), 1u);
    EXPECT_EQ(s.min, 0.0);
}

}  // namespace
}  // namespace isohex::pipeline

#include <algorithm>

#include <gtest/gtest.h>

#include "isohex/smoothing/Colouring.hpp"
#include "support/Blocks.hpp"

using namespace isohex;
using namespace isohex::smoothing;

TEST(Colouring, NodesSharingAHexNeverShareAColour) {
    const HexMesh m = test::makeBlock(5, 4, 3);
    const Topology topo = buildTopology(m);
    std::vector<std::uint8_t> movable(m.nodeCount(), 1);
    movable[7] = 0;
    const NodeColouring c = colourNodes(m, topo.nodeHexes, movable);
    EXPECT_EQ(c.colour[7], -1);
    for (const Hex& h : m.hexes)
        for (int i = 0; i < 8; ++i)
            for (int j = i + 1; j < 8; ++j)
                if (c.colour[h[i]] >= 0) {
                    EXPECT_NE(c.colour[h[i]], c.colour[h[j]]);
                }
    EXPECT_LE(c.classes.size(), 27u);  // at most one more than the 26 neighbours of a grid node
    std::size_t total = 0;
    for (const auto& cls : c.classes) {
        EXPECT_TRUE(std::is_sorted(cls.begin(), cls.end()));
        total += cls.size();
    }
    EXPECT_EQ(total, m.nodeCount() - 1);
}

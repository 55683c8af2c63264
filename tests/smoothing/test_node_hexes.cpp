// NodeHexes, the worst-hex pass's view of the hexes around one node: its
// gradient where value() was just taken (the frame value() found lowest,
// rebuilt alone) must be the gradient a fresh search of all moving frames
// gives, bit for bit, or the mean rounds would take other steps.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "../../smoothing/src/NodeHexes.hpp"
#include "support/Blocks.hpp"

using namespace isohex;
using isohex::smoothing::detail::NodeHexes;
using namespace isohex::vec;

namespace {

bool sameBits(const Vec3& a, const Vec3& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// A block with its nodes moved by `amount` of an edge, differently each.
HexMesh jitteredBlock(int n, double amount, double seed) {
    HexMesh m = test::makeBlock(n, n, n);
    for (std::size_t v = 0; v < m.nodeCount(); ++v)
        for (int c = 0; c < 3; ++c)
            m.nodes[v][static_cast<std::size_t>(c)] +=
                amount * std::sin(12.9898 * seed + 78.233 * static_cast<double>(v) + 37.719 * c);
    return m;
}

}  // namespace

TEST(NodeHexes, GradientAfterValuesAtThePointEqualsAFreshOne) {
    std::size_t compared = 0, nonzero = 0, revisited = 0;
    for (int r = 0; r < 20; ++r) {
        // mild and strong jitter: with 0.45 some frames invert or come
        // close to collapsing, so every kind of lowest frame occurs
        const HexMesh m = jitteredBlock(2, r % 2 ? 0.45 : 0.15, r);
        const Topology topo = buildTopology(m);
        for (std::size_t v = 0; v < m.nodeCount(); ++v) {
            const Index iv = static_cast<Index>(v);
            for (int k = 0; k < 4; ++k) {
                const Vec3 p = m.nodes[v] + Vec3{0.1 * std::sin(k + 0.3 * r), 0.1 * std::cos(2.0 * k), 0.05 * k};
                NodeHexes seen(m, topo, iv);
                for (std::size_t h = 0; h < seen.size(); ++h) seen.value(h, p);
                const Vec3 fresh = NodeHexes(m, topo, iv).summedGradient(p);
                const Vec3 reused = seen.summedGradient(p);
                ASSERT_TRUE(sameBits(reused, fresh)) << "node " << v << ", trial " << k << ", mesh " << r;
                ++compared;
                nonzero += std::abs(fresh[0]) + std::abs(fresh[1]) + std::abs(fresh[2]) > 0;
                // values taken elsewhere since (a refused trial): the
                // gradient at p must not use them
                if (seen.size() > 1) {
                    seen.value(0, m.nodes[v]);
                    ASSERT_TRUE(sameBits(seen.summedGradient(p), fresh)) << "node " << v << ", mesh " << r;
                    ++revisited;
                }
            }
        }
    }
    EXPECT_GT(compared, 2000u);
    EXPECT_GT(nonzero, 1000u);
    EXPECT_GT(revisited, 1000u);
}

// cutOut and putBack: the submesh around some free nodes, worked on alone and
// written back.
#include <gtest/gtest.h>

#include <algorithm>

#include "isohex/core/Submesh.hpp"
#include "isohex/core/Topology.hpp"
#include "support/Blocks.hpp"

namespace isohex {
namespace {

// A 4x4x4 block whose outer nodes are surface nodes of surface 0, material 2.
HexMesh classifiedBlock() {
    HexMesh m = test::makeBlock(4, 4, 4, 1.0, {0, 0, 0}, 2);
    m.surfaces.push_back({2, -1, "outer"});
    m.curves.push_back({-1, 2, 3});
    classifyBoundaryNodes(m);
    return m;
}

// The node at grid point (i, j, k) of the 4x4x4 block.
Index at(int i, int j, int k) { return static_cast<Index>((k * 5 + j) * 5 + i); }

// One free interior node: its 8 hexes and their 27 nodes, in the whole
// mesh's order; the free node keeps its class, the other 26 are Fixed.
TEST(Submesh, OneFreeNodeGivesItsHexesAndFixesTheOthers) {
    const HexMesh m = classifiedBlock();
    std::vector<std::uint8_t> free(m.nodeCount(), 0);
    const Index v = at(2, 2, 2);
    free[static_cast<std::size_t>(v)] = 1;
    const Submesh s = cutOut(m, free);
    ASSERT_EQ(s.mesh.hexCount(), 8u);
    ASSERT_EQ(s.mesh.nodeCount(), 27u);
    EXPECT_TRUE(std::is_sorted(s.from.begin(), s.from.end()));
    EXPECT_EQ(s.mesh.surfaces, m.surfaces);
    EXPECT_EQ(s.mesh.curves, m.curves);
    std::size_t freed = 0;
    for (std::size_t i = 0; i < s.from.size(); ++i) {
        EXPECT_EQ(s.mesh.nodes[i], m.nodes[static_cast<std::size_t>(s.from[i])]);
        if (s.from[i] == v) {
            EXPECT_EQ(s.free[i], 1);
            EXPECT_EQ(s.mesh.nodeClass[i], m.nodeClass[static_cast<std::size_t>(v)]);
            ++freed;
        } else {
            EXPECT_EQ(s.free[i], 0);
            EXPECT_EQ(s.mesh.nodeClass[i].kind, NodeKind::Fixed);
        }
    }
    EXPECT_EQ(freed, 1u);
    // each submesh hex is a whole-mesh hex with the same material, in order
    std::size_t next = 0;
    for (std::size_t h = 0; h < s.mesh.hexCount(); ++h) {
        Hex back{};
        for (std::size_t c = 0; c < 8; ++c) back[c] = s.from[static_cast<std::size_t>(s.mesh.hexes[h][c])];
        while (next < m.hexCount() && m.hexes[next] != back) ++next;
        ASSERT_LT(next, m.hexCount());
        EXPECT_EQ(s.mesh.material[h], 2);
    }
}

// A free surface node keeps its surface class, and its boundary quads in
// the submesh are its boundary quads in the whole mesh: the submesh's cut
// faces have no free node.
TEST(Submesh, AFreeNodesBoundaryIsItsOwn) {
    const HexMesh m = classifiedBlock();
    std::vector<std::uint8_t> free(m.nodeCount(), 0);
    const Index v = at(2, 2, 0);  // middle of the bottom face
    free[static_cast<std::size_t>(v)] = 1;
    const Submesh s = cutOut(m, free);
    ASSERT_EQ(s.mesh.hexCount(), 4u);
    const auto local = static_cast<std::size_t>(std::find(s.from.begin(), s.from.end(), v) - s.from.begin());
    EXPECT_EQ(s.mesh.nodeClass[local].kind, NodeKind::Surface);
    const Topology whole = buildTopology(m), part = buildTopology(s.mesh);
    auto boundaryQuadsAt = [](const Topology& t, Index node) {
        std::size_t n = 0;
        for (Index q : t.boundaryQuads) {
            const auto& nodes = t.quads[static_cast<std::size_t>(q)].nodes;
            n += std::find(nodes.begin(), nodes.end(), node) != nodes.end();
        }
        return n;
    };
    EXPECT_EQ(boundaryQuadsAt(part, static_cast<Index>(local)), boundaryQuadsAt(whole, v));
    EXPECT_EQ(boundaryQuadsAt(part, static_cast<Index>(local)), 4u);
}

// putBack writes every position back and the free nodes' classes, never the
// Fixed the other nodes have in the submesh.
TEST(Submesh, PutBackWritesPositionsAndFreeClasses) {
    HexMesh m = classifiedBlock();
    std::vector<std::uint8_t> free(m.nodeCount(), 0);
    const Index v = at(1, 1, 0), w = at(3, 3, 3);
    free[static_cast<std::size_t>(v)] = free[static_cast<std::size_t>(w)] = 1;
    Submesh s = cutOut(m, free);
    const HexMesh before = m;
    for (std::size_t i = 0; i < s.from.size(); ++i) {
        if (!s.free[i]) continue;
        s.mesh.nodes[i][2] += 0.25;
        s.mesh.nodeClass[i] = {NodeKind::Curve, 0};
    }
    putBack(s, m);
    for (std::size_t u = 0; u < m.nodeCount(); ++u) {
        const bool moved = static_cast<Index>(u) == v || static_cast<Index>(u) == w;
        EXPECT_EQ(m.nodes[u][2], before.nodes[u][2] + (moved ? 0.25 : 0.0)) << u;
        if (moved) {
            EXPECT_EQ(m.nodeClass[u], (NodeClass{NodeKind::Curve, 0}));
        } else {
            EXPECT_EQ(m.nodeClass[u], before.nodeClass[u]) << u;
        }
    }
}

// Nothing free: an empty submesh.
TEST(Submesh, NothingFreeIsEmpty) {
    const HexMesh m = classifiedBlock();
    const Submesh s = cutOut(m, std::vector<std::uint8_t>(m.nodeCount(), 0));
    EXPECT_EQ(s.mesh.hexCount(), 0u);
    EXPECT_EQ(s.mesh.nodeCount(), 0u);
    EXPECT_TRUE(s.from.empty());
}

}  // namespace
}  // namespace isohex

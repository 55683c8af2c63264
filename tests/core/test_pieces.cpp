// meshPieces: the separate pieces of a mesh (hexes joined through shared
// nodes), and how the report and the note describe them.
#include <gtest/gtest.h>

#include "isohex/core/Pieces.hpp"
#include "support/Blocks.hpp"

namespace isohex {
namespace {

// `b`'s hexes appended to `a` with their own nodes.
void append(HexMesh& a, const HexMesh& b) {
    const auto offset = static_cast<Index>(a.nodeCount());
    for (const Vec3& p : b.nodes) a.addNode(p);
    for (std::size_t h = 0; h < b.hexCount(); ++h) {
        Hex hex = b.hexes[h];
        for (Index& v : hex) v += offset;
        a.addHex(hex, b.material[h]);
    }
}

TEST(Pieces, NoneForNoHexesAndOneForABlock) {
    EXPECT_TRUE(meshPieces(HexMesh{}).empty());
    const auto one = meshPieces(test::makeBlock(3, 2, 2));
    ASSERT_EQ(one.size(), 1u);
    EXPECT_EQ(one[0].hexes, 12u);
    EXPECT_EQ(describePieces(one), "");
}

// Three blocks apart (the small ones first in hex order): three pieces, the
// most hexes first, each at the centroid of its first hex.
TEST(Pieces, BlocksApartArePiecesMostHexesFirst) {
    HexMesh m = test::makeBlock(1, 1, 1, 1.0, {10, 0, 0});
    append(m, test::makeBlock(2, 1, 1, 1.0, {20, 0, 0}));
    append(m, test::makeBlock(4, 4, 4));
    const auto pieces = meshPieces(m);
    ASSERT_EQ(pieces.size(), 3u);
    EXPECT_EQ(pieces[0].hexes, 64u);
    EXPECT_EQ(pieces[1].hexes, 2u);
    EXPECT_EQ(pieces[2].hexes, 1u);
    EXPECT_EQ(pieces[0].at, (Vec3{0.5, 0.5, 0.5}));
    EXPECT_EQ(pieces[1].at, (Vec3{20.5, 0.5, 0.5}));
    EXPECT_EQ(pieces[2].at, (Vec3{10.5, 0.5, 0.5}));
    EXPECT_EQ(describePieces(pieces),
              "3 separate pieces: the largest has 64 hexes, the other 2 have 3 hexes together (the biggest of them 2 "
              "hexes, at (20.5, 0.5, 0.5))");
    const nlohmann::json j = toJson(pieces);
    EXPECT_EQ(j["count"], 3);
    EXPECT_EQ(j["largest_hexes"], 64);
    EXPECT_EQ(j["other_hexes"], 3);
    ASSERT_EQ(j["others"].size(), 2u);
    EXPECT_EQ(j["others"][0]["hexes"], 2);
}

// Hexes that share only one node are one piece (a solver's matrix couples
// them there); two pieces read "the other has N hexes, at (...)".
TEST(Pieces, ASharedNodeJoinsAndTwoPiecesReadAsAPair) {
    HexMesh m = test::makeBlock(2, 2, 2);
    HexMesh corner = test::makeBlock(1, 1, 1, 1.0, {2, 2, 2});
    append(m, corner);
    // the corner hex's node 0 is the block's far corner node (2, 2, 2), index 26
    const auto shared = static_cast<Index>(26);
    ASSERT_EQ(m.nodes[static_cast<std::size_t>(shared)], (Vec3{2, 2, 2}));
    HexMesh joined = m;
    joined.hexes.back()[0] = shared;
    EXPECT_EQ(meshPieces(joined).size(), 1u);
    const auto apart = meshPieces(m);
    ASSERT_EQ(apart.size(), 2u);
    EXPECT_EQ(describePieces(apart), "2 separate pieces: the largest has 8 hexes, the other has 1 hex, at (2.5, 2.5, 2.5)");
}

TEST(Pieces, ListsAtMostTenOthersAndGroupsThousands) {
    HexMesh m = test::makeBlock(20, 10, 10);  // 2,000 hexes
    for (int i = 0; i < 12; ++i) append(m, test::makeBlock(1, 1, 1, 1.0, {30.0 + 2 * i, 0, 0}));
    const auto pieces = meshPieces(m);
    ASSERT_EQ(pieces.size(), 13u);
    const nlohmann::json j = toJson(pieces);
    EXPECT_EQ(j["others"].size(), kMaxPiecesListed);
    EXPECT_EQ(j["other_hexes"], 12);
    EXPECT_EQ(describePieces(pieces).rfind("13 separate pieces: the largest has 2,000 hexes, the other 12 have 12 hexes together (the biggest of them 1 hex, ", 0), 0u)
        << describePieces(pieces);
}

}  // namespace
}  // namespace isohex

#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include <tbb/global_control.h>

#include "isohex/core/Dual.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"
#include "isohex/core/Topology.hpp"
#include "support/Blocks.hpp"

using namespace isohex;
using isohex::test::makeBlock;

namespace {
// Closed-form counts for an a x b x c block of hexes.
std::size_t blockQuads(std::size_t a, std::size_t b, std::size_t c) {
    return (a + 1) * b * c + a * (b + 1) * c + a * b * (c + 1);
}
std::size_t blockEdges(std::size_t a, std::size_t b, std::size_t c) {
    return a * (b + 1) * (c + 1) + (a + 1) * b * (c + 1) + (a + 1) * (b + 1) * c;
}
// A 4x3x3 block whose every other hex is material 3 (interfaces everywhere).
HexMesh twoMaterialBlock() {
    HexMesh block = makeBlock(4, 3, 3);
    for (std::size_t h = 0; h < block.hexCount(); h += 2) block.material[h] = 3;
    return block;
}

// A hex and two more on its bottom face (a non-manifold "book").
HexMesh bookOfThree() {
    HexMesh m = makeBlock(1, 1, 1);
    for (int k = 0; k < 2; ++k) {
        Hex h = m.hexes[0];
        for (int i = 4; i < 8; ++i) {
            Vec3 p = m.nodes[h[i]];
            p[0] += 2.0 * (k + 1);
            h[i] = m.addNode(p);
        }
        m.addHex(h);
    }
    return m;
}
}  // namespace

TEST(Topology, BlockHasClosedFormCounts) {
    const HexMesh m = makeBlock(4, 3, 2);
    const Topology t = buildTopology(m);
    EXPECT_EQ(t.quads.size(), blockQuads(4, 3, 2));
    EXPECT_EQ(t.edges.size(), blockEdges(4, 3, 2));
    EXPECT_EQ(t.boundaryQuads.size(), 2u * (4 * 3 + 3 * 2 + 4 * 2));
    EXPECT_EQ(t.boundaryNodes.size(), 5u * 4 * 3 - 3u * 2 * 1);
    EXPECT_TRUE(t.interfaceQuads.empty());
    EXPECT_TRUE(t.overfullQuads.empty());
}

TEST(Topology, BoundaryQuadNormalsPointOutOfTheirHex) {
    const HexMesh m = makeBlock(3, 3, 3);
    const Topology t = buildTopology(m);
    for (Index q : t.boundaryQuads) {
        const auto& n = t.quads[q].nodes;
        Vec3 c{0, 0, 0}, fc{0, 0, 0};
        for (Index v : m.hexes[t.quads[q].hex[0]])
            for (int d = 0; d < 3; ++d) c[d] += m.nodes[v][d] / 8;
        for (Index v : n)
            for (int d = 0; d < 3; ++d) fc[d] += m.nodes[v][d] / 4;
        const Vec3& p0 = m.nodes[n[0]];
        const Vec3& p1 = m.nodes[n[1]];
        const Vec3& p3 = m.nodes[n[3]];
        const Vec3 a{p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
        const Vec3 b{p3[0] - p0[0], p3[1] - p0[1], p3[2] - p0[2]};
        const Vec3 normal{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
        const double out = normal[0] * (fc[0] - c[0]) + normal[1] * (fc[1] - c[1]) + normal[2] * (fc[2] - c[2]);
        EXPECT_GT(out, 0) << "quad " << q;
    }
}

TEST(Topology, EveryHexFaceAndEdgeIsFoundAgain) {
    const HexMesh m = makeBlock(3, 2, 2);
    const Topology t = buildTopology(m);
    for (std::size_t h = 0; h < m.hexes.size(); ++h) {
        for (int f = 0; f < 6; ++f) {
            const Quad& q = t.quads[t.hexQuads[h][f]];
            EXPECT_TRUE(q.hex[0] == Index(h) || q.hex[1] == Index(h));
        }
        for (int e = 0; e < 12; ++e) {
            const auto& edge = t.edges[t.hexEdges[h][e]];
            const auto& le = hexcell::kEdges[e];
            const std::set<Index> want{m.hexes[h][le[0]], m.hexes[h][le[1]]};
            EXPECT_EQ((std::set<Index>{edge[0], edge[1]}), want);
        }
    }
}

TEST(Topology, NodeHexAdjacencyMatchesConnectivity) {
    const HexMesh m = makeBlock(2, 2, 2);
    const Topology t = buildTopology(m);
    // the centre node of a 2x2x2 block is in all 8 hexes; a corner node in one
    const Index centre = 13;
    EXPECT_EQ(t.nodeHexes.size(centre), 8u);
    EXPECT_EQ(t.nodeHexes.size(0), 1u);
    for (std::size_t v = 0; v < m.nodes.size(); ++v)
        for (const Index* h = t.nodeHexes.begin(v); h != t.nodeHexes.end(v); ++h) {
            const auto& hex = m.hexes[*h];
            EXPECT_NE(std::find(hex.begin(), hex.end(), Index(v)), hex.end());
        }
}

TEST(Topology, MaterialInterfacesAreFoundAndGroupedIntoSurfaces) {
    HexMesh m = makeBlock(4, 2, 2);
    for (std::size_t h = 0; h < m.hexes.size(); ++h) m.material[h] = (h % 4) < 2 ? 1 : 2;
    const Topology t = buildTopology(m);
    EXPECT_EQ(t.interfaceQuads.size(), 4u);
    const auto patches = surfacePatches(m, t);
    ASSERT_EQ(patches.size(), 3u);
    EXPECT_EQ(patches[0].tag.inside, 1);
    EXPECT_EQ(patches[0].tag.outside, -1);
    EXPECT_EQ(patches[1].tag.inside, 1);
    EXPECT_EQ(patches[1].tag.outside, 2);
    EXPECT_EQ(patches[1].quads.size(), 4u);
    EXPECT_EQ(patches[2].tag.inside, 2);
    EXPECT_EQ(patches[0].quads.size() + patches[2].quads.size(), t.boundaryQuads.size());
    for (const auto& [h, f] : patches[1].hexFaces) EXPECT_EQ(m.material[h], 1);
}

TEST(Topology, QuadInThreeHexesIsListedAsOverfull) {
    const HexMesh m = bookOfThree();
    const Topology t = buildTopology(m);
    ASSERT_EQ(t.overfullQuads.size(), 1u);
    EXPECT_EQ(t.quadHexesAll.size(t.overfullQuads[0]), 3u);
}

// The parts node moves need are those of the full topology; the two they do
// not need are left empty, and what needs them refuses such a topology.
TEST(Topology, NodeMovesPartsEqualTheFullTopologysAndLeaveTheRestEmpty) {
    HexMesh m = makeBlock(5, 4, 3);
    for (std::size_t h = 0; h < m.hexCount(); h += 3) m.material[h] = 2;  // interfaces
    const Topology all = buildTopology(m);
    const Topology lean = buildTopology(m, TopologyParts::NodeMoves);
    ASSERT_EQ(lean.quads.size(), all.quads.size());
    for (std::size_t q = 0; q < all.quads.size(); ++q) {
        EXPECT_EQ(lean.quads[q].nodes, all.quads[q].nodes);
        EXPECT_EQ(lean.quads[q].hex, all.quads[q].hex);
        EXPECT_EQ(lean.quads[q].localFace, all.quads[q].localFace);
    }
    EXPECT_EQ(lean.hexQuads, all.hexQuads);
    EXPECT_EQ(lean.edges, all.edges);
    EXPECT_EQ(lean.nodeHexes.offsets, all.nodeHexes.offsets);
    EXPECT_EQ(lean.nodeHexes.items, all.nodeHexes.items);
    EXPECT_FALSE(all.interfaceQuads.empty());
    EXPECT_EQ(lean.boundaryQuads, all.boundaryQuads);
    EXPECT_EQ(lean.interfaceQuads, all.interfaceQuads);
    EXPECT_EQ(lean.overfullQuads, all.overfullQuads);
    EXPECT_EQ(lean.nodeOnBoundary, all.nodeOnBoundary);
    EXPECT_EQ(lean.boundaryNodes, all.boundaryNodes);
    EXPECT_TRUE(lean.hexEdges.empty());
    EXPECT_TRUE(lean.quadHexesAll.items.empty());
    EXPECT_THROW(edgeBetween(m, lean, m.hexes[0][0], m.hexes[0][1]), Error);
    EXPECT_NE(edgeBetween(m, all, m.hexes[0][0], m.hexes[0][1]), kNone);
    EXPECT_THROW(requireTopologyOf(m, lean, "test", TopologyParts::All), Error);
    EXPECT_NO_THROW(requireTopologyOf(m, lean, "test"));
}

// The surface parts are the full topology's surface quads, in the same order
// and for any thread count, with its node rows, edges and boundary flags;
// nothing per hex is kept. The book's quad with three holders is on no surface.
TEST(Topology, SurfaceMovesPartsAreTheFullTopologysSurfaceQuadsInOrderWithItsEdges) {
    HexMesh mixed = makeBlock(40, 30, 20);  // several parallel ranges of hexes
    for (std::size_t h = 0; h < mixed.hexCount(); h += 7) mixed.material[h] = 2;
    for (const HexMesh& m : {mixed, twoMaterialBlock(), bookOfThree()}) {
        const Topology all = buildTopology(m);
        for (int threads : {1, 2}) {
            tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
            const Topology lean = buildTopology(m, TopologyParts::SurfaceMoves);
            std::vector<Index> surface(all.boundaryQuads);
            surface.insert(surface.end(), all.interfaceQuads.begin(), all.interfaceQuads.end());
            std::sort(surface.begin(), surface.end());
            ASSERT_EQ(lean.quads.size(), surface.size());
            EXPECT_LT(lean.quads.size(), all.quads.size());
            std::vector<Index> boundary, interface;
            for (std::size_t i = 0; i < surface.size(); ++i) {
                const Quad& a = all.quads[surface[i]];
                EXPECT_EQ(lean.quads[i].nodes, a.nodes);
                EXPECT_EQ(lean.quads[i].hex, a.hex);
                EXPECT_EQ(lean.quads[i].localFace, a.localFace);
                (a.boundary() ? boundary : interface).push_back(static_cast<Index>(i));
            }
            EXPECT_EQ(lean.boundaryQuads, boundary);
            EXPECT_EQ(lean.interfaceQuads, interface);
            EXPECT_EQ(lean.nodeHexes.offsets, all.nodeHexes.offsets);
            EXPECT_EQ(lean.nodeHexes.items, all.nodeHexes.items);
            EXPECT_EQ(lean.nodeOnBoundary, all.nodeOnBoundary);
            EXPECT_EQ(lean.boundaryNodes, all.boundaryNodes);
            EXPECT_EQ(lean.edges, all.edges);
            EXPECT_TRUE(lean.hexQuads.empty());
            EXPECT_TRUE(lean.hexEdges.empty());
            EXPECT_TRUE(lean.overfullQuads.empty());
        }
    }
}

TEST(Topology, OverfullQuadIsFoundWithoutTheHolderLists) {
    EXPECT_EQ(buildTopology(bookOfThree(), TopologyParts::NodeMoves).overfullQuads.size(), 1u);
}

// Added one at a time, the parts NodeMoves leaves out are the full topology's,
// also where a quad has three holders.
TEST(Topology, PartsAddedLaterEqualTheFullTopologys) {
    for (const HexMesh& m : {twoMaterialBlock(), bookOfThree()}) {
        const Topology all = buildTopology(m);
        Topology t = buildTopology(m, TopologyParts::NodeMoves);
        addQuadHolders(t, m);
        EXPECT_EQ(t.quadHexesAll.offsets, all.quadHexesAll.offsets);
        EXPECT_EQ(t.quadHexesAll.items, all.quadHexesAll.items);
        EXPECT_TRUE(t.hexEdges.empty());
        addHexEdges(t, m);
        EXPECT_EQ(t.hexEdges, all.hexEdges);
        EXPECT_EQ(t.edges, all.edges);
    }
}

TEST(Topology, OutOfRangeNodeIsAnError) {
    HexMesh m = makeBlock(1, 1, 1);
    m.hexes[0][3] = 99;
    EXPECT_THROW(buildTopology(m), Error);
}

TEST(Topology, ResultDoesNotDependOnThreadCount) {
    HexMesh m = makeBlock(12, 9, 7);
    // scramble node numbering so buckets see interleaved work
    Topology one, many;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        one = buildTopology(m);
    }
    many = buildTopology(m);
    ASSERT_EQ(one.quads.size(), many.quads.size());
    for (std::size_t q = 0; q < one.quads.size(); ++q) {
        EXPECT_EQ(one.quads[q].nodes, many.quads[q].nodes);
        EXPECT_EQ(one.quads[q].hex, many.quads[q].hex);
    }
    EXPECT_EQ(one.edges, many.edges);
    EXPECT_EQ(one.hexEdges, many.hexEdges);
    EXPECT_EQ(one.nodeHexes.items, many.nodeHexes.items);
}

TEST(Dual, BlockSheetsAreItsGridPlanes) {
    const HexMesh m = makeBlock(4, 3, 2);
    const Topology t = buildTopology(m);
    const DualSheets s = buildSheets(m, t);
    EXPECT_EQ(s.count(), 4u + 3u + 2u);
    // every sheet of a block is one layer: its hexes are a full slab
    std::multiset<std::size_t> sizes;
    for (std::size_t i = 0; i < s.count(); ++i) sizes.insert(s.sheetHexes.size(i));
    EXPECT_EQ(sizes.count(3 * 2), 4u);  // layers across x hold 3*2 hexes
    EXPECT_EQ(sizes.count(4 * 2), 3u);
    EXPECT_EQ(sizes.count(4 * 3), 2u);
    for (std::size_t h = 0; h < m.hexes.size(); ++h)
        for (int d = 0; d < 3; ++d)
            for (int k = 0; k < 4; ++k) EXPECT_EQ(s.edgeSheet[t.hexEdges[h][4 * d + k]], s.hexSheets[h][d]);
}

TEST(Dual, BlockChordsAreItsRowsOfHexes) {
    const HexMesh m = makeBlock(4, 3, 2);
    const Topology t = buildTopology(m);
    const DualChords c = buildChords(m, t);
    EXPECT_EQ(c.count(), 3u * 2 + 4u * 2 + 4u * 3);
    for (std::size_t i = 0; i < c.count(); ++i) {
        const std::size_t n = c.chordHexes.size(i);
        EXPECT_TRUE(n == 4 || n == 3 || n == 2) << n;
        // a stack of n hexes has n + 1 quads
        EXPECT_EQ(c.chordQuads.size(i), n + 1);
    }
}

TEST(Dual, SheetOfRingClosesOnItself) {
    // a ring of 8 hexes around a square hole: the sheet across the ring is closed
    HexMesh m;
    const double pts[8][2] = {{0, 0}, {1, 0}, {2, 0}, {2, 1}, {2, 2}, {1, 2}, {0, 2}, {0, 1}};
    const double in[8][2] = {{0.5, 0.5}, {1, 0.5}, {1.5, 0.5}, {1.5, 1}, {1.5, 1.5}, {1, 1.5}, {0.5, 1.5}, {0.5, 1}};
    Index outer[2][8], inner[2][8];
    for (int z = 0; z < 2; ++z)
        for (int i = 0; i < 8; ++i) {
            outer[z][i] = m.addNode({pts[i][0], pts[i][1], double(z)});
            inner[z][i] = m.addNode({in[i][0], in[i][1], double(z)});
        }
    for (int i = 0; i < 8; ++i) {
        const int j = (i + 1) % 8;
        m.addHex({outer[0][i], outer[0][j], inner[0][j], inner[0][i], outer[1][i], outer[1][j], inner[1][j], inner[1][i]});
    }
    const Topology t = buildTopology(m);
    const DualSheets s = buildSheets(m, t);
    const DualChords c = buildChords(m, t);
    // sheets: the z-layer and the closed cylinder between inner and outer wall
    // hold all 8 hexes; each of the 8 sheets cutting the ring radially holds one
    EXPECT_EQ(s.count(), 10u);
    int full = 0;
    for (std::size_t i = 0; i < s.count(); ++i) {
        if (s.sheetHexes.size(i) == 8) {
            ++full;
            EXPECT_EQ(s.sheetEdges.size(i), 16u);
        } else {
            EXPECT_EQ(s.sheetHexes.size(i), 1u);
        }
    }
    EXPECT_EQ(full, 2);
    EXPECT_EQ(c.count(), 17u);
    // the chord around the ring is closed: 8 hexes, 8 quads (no end faces)
    bool closedChord = false;
    for (std::size_t i = 0; i < c.count(); ++i)
        if (c.chordHexes.size(i) == 8 && c.chordQuads.size(i) == 8) closedChord = true;
    EXPECT_TRUE(closedChord);
}

// validate()'s turns: the quads with their holders first and no edges, then
// the edges added, each as the full topology has them; what needs the edges
// refuses the topology before they are added.
TEST(Topology, QuadHolderPartsThenEdgesEqualTheFullTopologys) {
    for (const HexMesh& m : {twoMaterialBlock(), bookOfThree()}) {
        const Topology all = buildTopology(m);
        Topology t = buildTopology(m, TopologyParts::QuadHolders);
        EXPECT_EQ(t.hexQuads, all.hexQuads);
        EXPECT_EQ(t.quadHexesAll.offsets, all.quadHexesAll.offsets);
        EXPECT_EQ(t.quadHexesAll.items, all.quadHexesAll.items);
        EXPECT_EQ(t.overfullQuads, all.overfullQuads);
        EXPECT_EQ(t.boundaryNodes, all.boundaryNodes);
        EXPECT_TRUE(t.edges.empty());
        EXPECT_TRUE(t.hexEdges.empty());
        EXPECT_NO_THROW(requireTopologyOf(m, t, "test", TopologyParts::QuadHolders));
        EXPECT_THROW(requireTopologyOf(m, t, "test"), Error);
        addHexEdges(t, m);
        EXPECT_EQ(t.edges, all.edges);
        EXPECT_EQ(t.hexEdges, all.hexEdges);
        EXPECT_NO_THROW(requireTopologyOf(m, t, "test"));
    }
    const HexMesh block = twoMaterialBlock();
    EXPECT_THROW(requireTopologyOf(block, buildTopology(block, TopologyParts::NodeMoves), "test",
                                   TopologyParts::QuadHolders),
                 Error);
}

// Every hex's edge ids name edges with that hex edge's two ends, each edge
// once, also where a hex repeats a node (collapsed edges, and a hex holding
// one edge twice, as its local edges 0 and 1).
TEST(Topology, HexEdgeIdsNameTheHexesOwnEnds) {
    HexMesh m = makeBlock(3, 2, 2);
    m.hexes[4][1] = m.hexes[4][0];  // edge 0 of hex 4 collapses to a point
    m.hexes[7][6] = m.hexes[7][2];
    m.hexes[9][2] = m.hexes[9][0];  // local edges 0 and 1 of hex 9 join the same two nodes
    m.hexes[9][3] = m.hexes[9][1];
    for (TopologyParts parts : {TopologyParts::All, TopologyParts::QuadHolders}) {
        Topology t = buildTopology(m, parts);
        if (parts == TopologyParts::QuadHolders) addHexEdges(t, m);
        std::set<std::array<Index, 2>> unique(t.edges.begin(), t.edges.end());
        EXPECT_EQ(unique.size(), t.edges.size());
        for (std::size_t h = 0; h < m.hexCount(); ++h)
            for (int e = 0; e < 12; ++e) {
                const Index a = m.hexes[h][hexcell::kEdges[e][0]], b = m.hexes[h][hexcell::kEdges[e][1]];
                const std::array<Index, 2> ends{std::min(a, b), std::max(a, b)};
                ASSERT_GE(t.hexEdges[h][e], 0);
                EXPECT_EQ(t.edges[static_cast<std::size_t>(t.hexEdges[h][e])], ends) << "hex " << h << " edge " << e;
            }
    }
}

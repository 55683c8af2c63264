#include <gtest/gtest.h>

#include <string>

#include <algorithm>
#include <cmath>
#include <set>

#include <tbb/global_control.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Collapse.hpp"
#include "isohex/core/Dice.hpp"
#include "isohex/core/Pillow.hpp"
#include "isohex/core/SheetSelection.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/core/VecMath.hpp"
#include "support/Blocks.hpp"

using namespace isohex;
using isohex::test::makeBlock;

namespace {

// Number of faces of each hex that lie on the given quad list.
std::vector<int> facesOn(const HexMesh& m, const Topology& t, const std::vector<Index>& quads) {
    std::vector<int> n(m.hexCount(), 0);
    for (Index q : quads) {
        ++n[t.quads[q].hex[0]];
        if (t.quads[q].hex[1] != kNone) ++n[t.quads[q].hex[1]];
    }
    return n;
}

std::size_t invertedCount(const HexMesh& m) {
    std::size_t n = 0;
    for (std::size_t h = 0; h < m.hexCount(); ++h) n += minCornerDeterminant(hexCoords(m, h)) <= 0;
    return n;
}

HexMesh classifiedBlock(int a, int b, int c) {
    HexMesh m = makeBlock(a, b, c);
    classifyBoundaryNodes(m);
    return m;
}

}  // namespace

TEST(Pillow, WholeSolidGetsOneHexPerSurfaceQuad) {
    HexMesh m = classifiedBlock(4, 3, 3);
    const std::size_t quadsBefore = buildTopology(m).boundaryQuads.size();
    const std::size_t hexesBefore = m.hexCount();
    std::vector<Index> all(m.hexCount());
    for (std::size_t h = 0; h < all.size(); ++h) all[h] = static_cast<Index>(h);
    const PillowResult r = pillow(m, all);
    EXPECT_EQ(m.hexCount() - hexesBefore, quadsBefore);
    EXPECT_EQ(r.firstNewHex, static_cast<Index>(hexesBefore));
    EXPECT_TRUE(validate(m).ok());
    EXPECT_EQ(invertedCount(m), 0u);
    EXPECT_EQ(r.invertedAtStart, 0u);
}

TEST(Pillow, EveryHexHasAtMostOneFaceOnTheSurfaceAfterwards) {
    HexMesh m = classifiedBlock(3, 3, 3);
    const Topology before = buildTopology(m);
    const auto facesBefore = facesOn(m, before, before.boundaryQuads);
    EXPECT_EQ(*std::max_element(facesBefore.begin(), facesBefore.end()), 3);  // block corners own 3
    pillowAllMaterials(m);
    const Topology after = buildTopology(m);
    const auto n = facesOn(m, after, after.boundaryQuads);
    EXPECT_EQ(*std::max_element(n.begin(), n.end()), 1);
}

TEST(Pillow, SurfaceNodesKeepTheirExactPositionsAndIndices) {
    HexMesh m = classifiedBlock(3, 2, 2);
    const HexMesh before = m;
    pillowAllMaterials(m);
    for (std::size_t v = 0; v < before.nodeCount(); ++v) {
        EXPECT_EQ(m.nodes[v], before.nodes[v]) << v;  // bitwise
        EXPECT_EQ(m.nodeClass[v], before.nodeClass[v]);
    }
    // the boundary surface is the same set of quads over the same nodes
    auto quadSet = [](const HexMesh& x) {
        const Topology t = buildTopology(x);
        std::set<std::array<Index, 4>> s;
        for (Index q : t.boundaryQuads) {
            auto k = t.quads[q].nodes;
            std::sort(k.begin(), k.end());
            s.insert(k);
        }
        return s;
    };
    EXPECT_EQ(quadSet(m), quadSet(before));
}

TEST(Pillow, TwoMaterialsGiveTwoSheetsAtTheInterface) {
    HexMesh m = makeBlock(4, 2, 2);
    for (std::size_t h = 0; h < m.hexCount(); ++h) m.material[h] = (h % 4) < 2 ? 1 : 2;
    classifyBoundaryNodes(m);
    const std::size_t hexesBefore = m.hexCount();
    const auto results = pillowAllMaterials(m);
    ASSERT_EQ(results.size(), 2u);
    EXPECT_TRUE(validate(m).ok());
    EXPECT_EQ(invertedCount(m), 0u);
    const Topology t = buildTopology(m);
    // every interface quad now lies between two hexes that are both new (one per sheet)
    ASSERT_EQ(t.interfaceQuads.size(), 4u);
    for (Index q : t.interfaceQuads) {
        EXPECT_GE(t.quads[q].hex[0], static_cast<Index>(hexesBefore));
        EXPECT_GE(t.quads[q].hex[1], static_cast<Index>(hexesBefore));
    }
    // and two fundamental sheets were made
    const DualSheets s = buildSheets(m, t);
    EXPECT_GE(fundamentalSheets(m, t, s).size(), 2u);
}

TEST(Pillow, RefusesANonManifoldShrinkSetBoundary) {
    // two cubes sharing only an edge: their union's boundary is pinched
    HexMesh m = makeBlock(2, 2, 1);
    m.hexes.erase(m.hexes.begin() + 1, m.hexes.begin() + 3);  // keep hexes 0 and 3 (diagonal)
    m.material.resize(2);
    const HexMesh before = m;
    try {
        pillow(m, {0, 1});
        FAIL() << "expected an error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("not a closed 2-manifold"), std::string::npos) << e.what();
    }
    EXPECT_EQ(m.hexes, before.hexes);
    EXPECT_EQ(m.nodes, before.nodes);
}

TEST(Pillow, ASubsetGetsASheetAgainstTheRestOfTheMesh) {
    HexMesh m = classifiedBlock(4, 4, 4);
    std::vector<Index> inner;
    for (int k = 1; k < 3; ++k)
        for (int j = 1; j < 3; ++j)
            for (int i = 1; i < 3; ++i) inner.push_back(static_cast<Index>((k * 4 + j) * 4 + i));
    const std::size_t before = m.hexCount();
    pillow(m, inner);
    EXPECT_EQ(m.hexCount() - before, 24u);  // the 2x2x2 cube has 24 boundary quads
    EXPECT_TRUE(validate(m).ok());
    EXPECT_EQ(invertedCount(m), 0u);
}

TEST(Pillow, CopiesStartTheirStepInsideWhereTheHexesUnderThemAreThin) {
    // A 6 x 6 x 6 block whose boundary nodes inside its faces are pulled in
    // towards the layer below, each to its own height of 0.1 to 1 edge above
    // it, as dual contouring leaves the hexes under a curved surface: many
    // are thinner than the copies' step of 0.3 of an edge. Shortening every
    // copy of an inverted hex together spread to their neighbours, and most
    // copies of the sheet ended within a few hundredths of an edge of their
    // nodes; each should go in as far as its own hexes allow.
    HexMesh m = makeBlock(6, 6, 6, 1.0, {-3, -3, -3});
    std::uint64_t x = 0x9E3779B97F4A7C15ull;
    for (Vec3& p : m.nodes) {
        const double outer = std::max({std::abs(p[0]), std::abs(p[1]), std::abs(p[2])});
        if (outer < 3) continue;
        x ^= x >> 12, x ^= x << 25, x ^= x >> 27;  // xorshift, reproducible
        const int onFaces = (std::abs(p[0]) == 3) + (std::abs(p[1]) == 3) + (std::abs(p[2]) == 3);
        const double height =  // the block's edges and corners stay: their hexes would fold
            onFaces > 1 ? 1.0 : 0.1 + 0.9 * static_cast<double>((x * 0x2545F4914F6CDD1Dull) >> 11) * 0x1p-53;
        for (double& c : p) c = std::clamp(c, -2.0, 2.0) + height * (c - std::clamp(c, -2.0, 2.0));
    }
    classifyBoundaryNodes(m);
    ASSERT_EQ(invertedCount(m), 0u);
    std::vector<Index> all(m.hexCount());
    for (std::size_t h = 0; h < all.size(); ++h) all[h] = static_cast<Index>(h);
    auto medianStep = [&](bool stepOnAlone, std::size_t& inverted) {
        using namespace vec;
        HexMesh p = m;
        PillowOptions o;
        o.stepOnAlone = stepOnAlone;
        const PillowResult r = pillow(p, all, o);
        inverted = invertedCount(p);
        EXPECT_EQ(r.invertedAtStart, inverted);
        std::vector<double> steps;
        for (std::size_t c = 0; c < r.copyOf.size(); ++c) {
            const Vec3& a = p.nodes[static_cast<std::size_t>(r.firstNewNode) + c];
            const Vec3& b = p.nodes[static_cast<std::size_t>(r.copyOf[c])];
            steps.push_back(vec::norm(a - b));
        }
        std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
        return steps[steps.size() / 2];
    };
    std::size_t invertedTogether = 0, invertedAlone = 0;
    const double together = medianStep(false, invertedTogether);
    const double alone = medianStep(true, invertedAlone);
    EXPECT_EQ(invertedAlone, 0u);
    EXPECT_GT(alone, 0.15);
    EXPECT_GT(alone, 2 * together);
}

TEST(Pillow, SameMeshForAnyThreadCountAndAnyOrderOfTheShrinkSet) {
    // A block with a cavity and a dent; the shrink set given sorted on one
    // thread, then reversed with repeats on several: the same mesh, bit for bit.
    const HexMesh base = classifiedBlock(8, 7, 6);
    std::vector<Index> shrink;
    for (Index h = 0; h < static_cast<Index>(base.hexCount()); ++h)
        if (h != 0 && h != (2 * 7 + 3) * 8 + 3) shrink.push_back(h);
    std::vector<HexMesh> meshes;
    std::vector<PillowResult> results;
    for (int threads : {1, 2, 4}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
        std::vector<Index> order = shrink;
        if (threads > 1) {
            std::reverse(order.begin(), order.end());
            order.insert(order.end(), shrink.begin(), shrink.begin() + 20);
        }
        HexMesh m = base;
        results.push_back(pillow(m, order));
        meshes.push_back(std::move(m));
    }
    EXPECT_TRUE(validate(meshes[0]).ok());
    for (std::size_t i = 1; i < meshes.size(); ++i) {
        EXPECT_EQ(meshes[i].hexes, meshes[0].hexes);
        EXPECT_EQ(meshes[i].nodes, meshes[0].nodes);
        EXPECT_EQ(meshes[i].nodeClass, meshes[0].nodeClass);
        EXPECT_EQ(meshes[i].material, meshes[0].material);
        EXPECT_EQ(results[i].copyOf, results[0].copyOf);
        EXPECT_EQ(results[i].invertedAtStart, results[0].invertedAtStart);
    }
}

TEST(Pillow, TheParityShortcutGivesTheSameSheetAsTheFullAdjacency) {
    // Shrink sets with holes, dents and several components inside a block:
    // the boundary found from the nodes the face parity marks must be the one
    // the full node -> hex adjacency gives, node for node and hex for hex.
    for (std::uint64_t seed : {1u, 2u, 3u}) {
        const HexMesh base = classifiedBlock(7, 6, 5);
        std::vector<Index> shrink;
        std::uint64_t x = seed * 0x9E3779B97F4A7C15ull;
        for (std::size_t h = 0; h < base.hexCount(); ++h) {
            x ^= x >> 12, x ^= x << 25, x ^= x >> 27;  // xorshift, reproducible
            if ((x * 0x2545F4914F6CDD1Dull) >> 62) shrink.push_back(static_cast<Index>(h));  // about 3 in 4
        }
        HexMesh fast = base, exact = base;
        PillowOptions o;
        std::string fastError, exactError;
        try {
            pillow(fast, shrink, o);
        } catch (const Error& e) {
            fastError = e.what();
        }
        o.exactBoundary = true;
        try {
            pillow(exact, shrink, o);
        } catch (const Error& e) {
            exactError = e.what();
        }
        EXPECT_EQ(fastError, exactError) << "seed " << seed;
        EXPECT_EQ(fast.hexes, exact.hexes) << "seed " << seed;
        EXPECT_EQ(fast.nodes, exact.nodes) << "seed " << seed;
    }
    // A manifold case that must succeed: a 5 x 5 x 5 block with its centre
    // hex left out (a cavity) and one corner hex left out (a dent).
    const HexMesh base = classifiedBlock(5, 5, 5);
    std::vector<Index> shrink;
    for (Index h = 0; h < 125; ++h)
        if (h != 62 && h != 0) shrink.push_back(h);
    HexMesh fast = base, exact = base;
    const PillowResult rf = pillow(fast, shrink);
    PillowOptions o;
    o.exactBoundary = true;
    pillow(exact, shrink, o);
    EXPECT_EQ(fast.hexes, exact.hexes);
    EXPECT_EQ(fast.nodes, exact.nodes);
    // 150 outer quads minus the dent's 3, plus the dent's 3 inner faces,
    // plus the cavity's 6
    EXPECT_EQ(fast.hexCount() - base.hexCount(), 156u);
    EXPECT_EQ(rf.firstNewHex, 125);
    EXPECT_TRUE(validate(fast).ok());
}

TEST(Dice, MultipliesTheSheetsHexesByCopiesPlusOne) {
    HexMesh m = classifiedBlock(4, 3, 2);
    const Topology t = buildTopology(m);
    const DualSheets s = buildSheets(m, t);
    const Index sheet = sheetThroughEdge(m, t, s, 0, 1);  // an x-edge: the layer i = 0
    const std::size_t layer = s.sheetHexes.size(sheet);
    EXPECT_EQ(layer, 6u);
    const std::size_t added = dice(m, t, s, sheet, 2);
    EXPECT_EQ(added, 2 * layer);
    EXPECT_EQ(m.hexCount(), 24u + 12u);
    EXPECT_TRUE(validate(m).ok());
    EXPECT_EQ(invertedCount(m), 0u);
    double vol = 0;
    for (std::size_t h = 0; h < m.hexCount(); ++h) vol += hexVolume(hexCoords(m, h));
    EXPECT_NEAR(vol, 24.0, 1e-12);
    // the diced layer is now three sheets of 6 hexes each
    const Topology t2 = buildTopology(m);
    const DualSheets s2 = buildSheets(m, t2);
    EXPECT_EQ(s2.count(), s.count() + 2);
}

TEST(Dice, ThenCollapsingTheCopiesRestoresCountsAndValidity) {
    HexMesh m = classifiedBlock(3, 3, 3);
    const std::size_t hexes = m.hexCount(), nodes = m.nodeCount();
    {
        const Topology t = buildTopology(m);
        const DualSheets s = buildSheets(m, t);
        dice(m, t, s, sheetThroughEdge(m, t, s, 0, 4 * 4), 2);  // a z-edge
    }
    EXPECT_EQ(m.hexCount(), hexes + 2 * 9);
    for (int i = 0; i < 2; ++i) {
        const Topology t = buildTopology(m);
        const DualSheets s = buildSheets(m, t);
        // a copy: a sheet whose edges all have a new (diced) node
        Index copySheet = kNone;
        for (std::size_t sh = 0; sh < s.count() && copySheet == kNone; ++sh) {
            bool allNew = true;
            for (const Index* e = s.sheetEdges.begin(sh); e != s.sheetEdges.end(sh); ++e)
                allNew = allNew && t.edges[*e][1] >= static_cast<Index>(nodes);
            if (allNew) copySheet = static_cast<Index>(sh);
        }
        ASSERT_NE(copySheet, kNone);
        collapse(m, t, s, copySheet);
    }
    EXPECT_EQ(m.hexCount(), hexes);
    EXPECT_EQ(m.nodeCount(), nodes);
    EXPECT_TRUE(validate(m).ok());
    EXPECT_EQ(invertedCount(m), 0u);
}

TEST(Collapse, RemovingThePillowRestoresTheOriginalMeshExactly) {
    HexMesh m = classifiedBlock(3, 3, 2);
    const HexMesh original = m;
    const PillowResult r = pillowAllMaterials(m).front();
    const Topology t = buildTopology(m);
    const DualSheets s = buildSheets(m, t);
    const Index sheet = sheetThroughEdge(m, t, s, r.firstNewNode, r.copyOf[0]);
    collapse(m, t, s, sheet);
    EXPECT_EQ(m.nodes, original.nodes);
    EXPECT_EQ(m.nodeClass, original.nodeClass);
    EXPECT_EQ(m.hexes, original.hexes);
    EXPECT_EQ(m.material, original.material);
}

TEST(Collapse, GivesTheCollapsedMeshsDefectKindsOnlyWhenItSucceeds) {
    HexMesh m = classifiedBlock(3, 3, 2);
    const PillowResult r = pillowAllMaterials(m).front();
    const Topology t = buildTopology(m);
    const DualSheets s = buildSheets(m, t);
    const Index pillow = sheetThroughEdge(m, t, s, r.firstNewNode, r.copyOf[0]);
    std::set<std::string> after{"not written"};
    collapse(m, t, s, pillow, topologicalDefects(m), &after);
    EXPECT_EQ(after, topologicalDefects(m));

    HexMesh plate = classifiedBlock(3, 3, 1);
    const Topology tp = buildTopology(plate);
    const DualSheets sp = buildSheets(plate, tp);
    std::set<std::string> untouched{"not written"};
    EXPECT_THROW(collapse(plate, tp, sp, sheetThroughEdge(plate, tp, sp, 0, 16), topologicalDefects(plate), &untouched),
                 Error);
    EXPECT_EQ(untouched, std::set<std::string>{"not written"});
}

TEST(Collapse, RefusesToCollapseASurfaceThroughTheSolid) {
    // in a 1-hex-thick plate every z-edge joins the top and bottom surfaces
    HexMesh m = classifiedBlock(3, 3, 1);
    const HexMesh before = m;
    const Topology t = buildTopology(m);
    const DualSheets s = buildSheets(m, t);
    const Index sheet = sheetThroughEdge(m, t, s, 0, 16);  // a z-edge
    EXPECT_THROW(collapse(m, t, s, sheet), Error);
    EXPECT_EQ(m.hexes, before.hexes);
}

TEST(SheetSelection, RandomSheetsAreDistinctReproducibleAndRespectExclusions) {
    HexMesh m = makeBlock(6, 5, 4);
    const Topology t = buildTopology(m);
    const DualSheets s = buildSheets(m, t);
    const auto a = randomSheets(s, 5, 42, {0, 1});
    const auto b = randomSheets(s, 5, 42, {0, 1});
    EXPECT_EQ(a, b);
    EXPECT_EQ(std::set<Index>(a.begin(), a.end()).size(), 5u);
    for (Index x : a) EXPECT_GT(x, 1);
    EXPECT_NE(randomSheets(s, 5, 43, {0, 1}), a);
    EXPECT_EQ(randomSheets(s, 100, 1).size(), s.count());
}

TEST(SheetSelection, FundamentalSheetIsFoundAfterPillowing) {
    HexMesh m = classifiedBlock(3, 3, 3);
    {
        const Topology t = buildTopology(m);
        const DualSheets s = buildSheets(m, t);
        EXPECT_TRUE(fundamentalSheets(m, t, s).empty());
    }
    pillowAllMaterials(m);
    const Topology t = buildTopology(m);
    const DualSheets s = buildSheets(m, t);
    const auto f = fundamentalSheets(m, t, s);
    ASSERT_EQ(f.size(), 1u);
    EXPECT_EQ(s.sheetHexes.size(f[0]), t.boundaryQuads.size());
    EXPECT_EQ(sheetsTouchingSurfaces(t, s).size(), s.count());
}

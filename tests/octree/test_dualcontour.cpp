#include <gtest/gtest.h>

#include <algorithm>
#include <iostream>
#include <set>

#include <cmath>

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include "AnalyticDomains.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/octree/DualContour.hpp"
#include "isohex/octree/GridEdits.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/LevelChoice.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/Regions.hpp"

using namespace isohex;
using namespace isohex::octree;
using namespace isohex::test;

namespace {

HexMesh mesh(const Domain& d, const Grid& g, ExtractOptions opt = {}, ExtractStats* st = nullptr) {
    Labels l = sampleLabels(d, g);
    repairNonManifold(l, d);
    return dualContourHexes(l, d, opt, st);
}

double maxBoundaryDistance(const HexMesh& m, const Sdf& f) {
    const Topology t = buildTopology(m);
    double worst = 0;
    for (Index v : t.boundaryNodes) worst = std::max(worst, std::abs(f(m.nodes[v])));
    return worst;
}

// Dual contouring alone may leave inverted boundary hexes (the reason the
// fundamental sheet is pillowed in afterwards); what it must deliver is a
// topologically valid mesh: every defect kind but inversion is an error here.
bool topologicallyValid(const HexMesh& m) {
    ValidityReport v = validate(m);
    v.defects.erase("inverted_hex");
    if (!v.ok()) ADD_FAILURE() << toJson(v).dump();
    return v.ok();
}

std::vector<std::int32_t> grid3(int n) { return std::vector<std::int32_t>(static_cast<std::size_t>(n) * n * n, 0); }
void set(std::vector<std::int32_t>& v, int n, int i, int j, int k, std::int32_t m = 1) {
    v[(static_cast<std::size_t>(k) * n + j) * n + i] = m;
}
// An n^3 grid with material 1 at the points lo..hi on every axis.
std::vector<std::int32_t> solidBlock(int n, int lo, int hi) {
    auto v = grid3(n);
    for (int k = lo; k <= hi; ++k)
        for (int j = lo; j <= hi; ++j)
            for (int i = lo; i <= hi; ++i) set(v, n, i, j, k);
    return v;
}

}  // namespace

TEST(DualContour, SphereIsValidClosedAndOnTheSurface) {
    const Sdf s = sphere({10, 10, 10}, 6.3);
    const AnalyticDomain d({s});
    const HexMesh m = mesh(d, unitGrid(21));
    EXPECT_GT(m.hexCount(), 700u);
    EXPECT_TRUE(topologicallyValid(m));
    // boundary nodes are QEF vertices on the sphere
    EXPECT_LT(maxBoundaryDistance(m, s), 0.1);
    const auto topo = regionTopology([&] {
        Labels l = sampleLabels(d, unitGrid(21));
        repairNonManifold(l, d);
        return l;
    }());
    ASSERT_EQ(topo.size(), 1u);
    EXPECT_EQ(topo[0].components, 1u);
    EXPECT_EQ(topo[0].euler, 2);
}

TEST(DualContour, OneHexPerInsidePointAndVolumeNearTheSphere) {
    const double r = 8.2;
    const AnalyticDomain d({sphere({12, 12, 12}, r)});
    Labels l = sampleLabels(d, unitGrid(25));
    repairNonManifold(l, d);
    std::size_t inside = 0;
    for (auto m : l.material) inside += m != 0;
    const HexMesh m = dualContourHexes(l, d);
    EXPECT_EQ(m.hexCount(), inside);
    double vol = 0;
    for (std::size_t h = 0; h < m.hexCount(); ++h) vol += hexVolume(hexCoords(m, h));
    const double exact = 4.0 / 3.0 * M_PI * r * r * r;
    EXPECT_NEAR(vol / exact, 1.0, 0.02);
}

TEST(DualContour, TorusKeepsGenusOne) {
    const AnalyticDomain d({torus({12, 12, 12}, 7, 2.6)});
    Labels l = sampleLabels(d, unitGrid(25));
    repairNonManifold(l, d);
    const auto topo = regionTopology(l);
    ASSERT_EQ(topo.size(), 1u);
    EXPECT_EQ(topo[0].components, 1u);
    EXPECT_EQ(topo[0].euler, 0);
    EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d)));
}

TEST(DualContour, TwoSpheresAlmostTouchingStayManifold) {
    const AnalyticDomain d({unite(sphere({7, 10, 10}, 4.45), sphere({16, 10, 10}, 4.45))});
    Labels l = sampleLabels(d, unitGrid(23));
    repairNonManifold(l, d);
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    const HexMesh m = dualContourHexes(l, d);
    EXPECT_TRUE(topologicallyValid(m));
}

TEST(DualContour, ThinPlateGivesAValidMesh) {
    const AnalyticDomain d({box({3, 3, 9.7}, {17, 17, 10.9})});
    const HexMesh m = mesh(d, unitGrid(21));
    EXPECT_GT(m.hexCount(), 0u);
    EXPECT_TRUE(topologicallyValid(m));
}

TEST(NonManifoldRepair, TwoCubesSharingAnEdge) {
    const int n = 6;
    auto v = grid3(n);
    set(v, n, 2, 2, 2);
    set(v, n, 3, 3, 2);  // diagonal neighbour in a plane: touches along an edge
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    EXPECT_GT(countNonManifoldBlocks(l), 0u);
    const RepairReport r = repairNonManifold(l, d);
    EXPECT_GT(r.nonManifoldBefore, 0u);
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d)));
}

TEST(NonManifoldRepair, PocketsTouchingAlongAnEdgeStayTwoPockets) {
    // Two one-point pockets of the outside inside a solid block, touching
    // along an edge: marching cubes draws two little spheres. Filling one or
    // joining them would lose one; the repair moves a pocket by a point.
    const int n = 12;
    auto v = solidBlock(n, 2, 9);
    set(v, n, 5, 5, 5, 0);
    set(v, n, 6, 6, 5, 0);
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    EXPECT_GT(countNonManifoldBlocks(l), 0u);
    repairNonManifold(l, d);
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    const auto t = regionTopology(l);
    ASSERT_EQ(t.size(), 1u);
    EXPECT_EQ(t[0].components, 3u);  // the block's outside and two pockets
    EXPECT_EQ(t[0].euler, 6);
    EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d)));
}

TEST(NonManifoldRepair, SpeckKeptApartWhereTheRegionsSaySo) {
    // A one-point speck touching a block along an edge: one region unless the
    // caller's regions (e.g. volumeToMesh's parts) keep it apart, in which
    // case it stays a speck (the block gives up the points it touches, or
    // the speck moves by a point).
    const int n = 10;
    auto v = grid3(n);
    for (int k = 2; k <= 6; ++k)
        for (int j = 2; j <= 6; ++j)
            for (int i = 2; i <= 6; ++i) set(v, n, i, j, k);
    set(v, n, 7, 7, 4);
    const PointSetDomain d({n, n, n}, v);
    Labels joined = sampleLabels(d, unitGrid(n));
    repairNonManifold(joined, d);
    EXPECT_EQ(countNonManifoldBlocks(joined), 0u);
    EXPECT_EQ(regionTopology(joined)[0].components, 1u);
    Labels apart = sampleLabels(d, unitGrid(n));
    std::vector<std::int32_t> regions(apart.material.size(), 0);
    regions[apart.grid.index(7, 7, 4)] = 1;
    repairNonManifold(apart, d, &regions);
    EXPECT_EQ(countNonManifoldBlocks(apart), 0u);
    const auto t = regionTopology(apart);
    EXPECT_EQ(t[0].components, 2u);
    EXPECT_EQ(t[0].euler, 4);
    EXPECT_TRUE(topologicallyValid(dualContourHexes(apart, d)));
}

TEST(NonManifoldRepair, TwoCubesSharingAVertex) {
    const int n = 6;
    auto v = grid3(n);
    set(v, n, 2, 2, 2);
    set(v, n, 3, 3, 3);
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    EXPECT_GT(countNonManifoldBlocks(l), 0u);
    repairNonManifold(l, d);
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d)));
}

TEST(NonManifoldRepair, CheckerboardIsRepaired) {
    const int n = 8;
    auto v = grid3(n);
    for (int k = 1; k < n - 1; ++k)
        for (int j = 1; j < n - 1; ++j)
            for (int i = 1; i < n - 1; ++i)
                if ((i + j + k) % 2 == 0) set(v, n, i, j, k);
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    EXPECT_GT(countNonManifoldBlocks(l), 10u);
    repairNonManifold(l, d);
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    const HexMesh m = dualContourHexes(l, d);
    EXPECT_TRUE(topologicallyValid(m));
}

TEST(NonManifoldRepair, OneVoxelThinSheetIsManifoldAlready) {
    const int n = 8;
    auto v = grid3(n);
    for (int j = 2; j < 6; ++j)
        for (int i = 2; i < 6; ++i) set(v, n, i, j, 4);
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    const HexMesh m = dualContourHexes(l, d);
    EXPECT_EQ(m.hexCount(), 16u);
    EXPECT_TRUE(topologicallyValid(m));
}

TEST(DualContour, AnisotropicObliqueGridGivesPositiveHexes) {
    const Sdf s = sphere({0, 0, 0}, 5.0);
    const AnalyticDomain d({s});
    Grid g;
    const double c = std::cos(0.4), sn = std::sin(0.4);
    g.axes = {{{0.8 * c, 0.8 * sn, 0}, {-0.6 * sn, 0.6 * c, 0}, {0, 0, 0.9}}};
    g.dims = {21, 27, 18};
    g.origin = {0, 0, 0};
    for (int a = 0; a < 3; ++a)
        for (int cc = 0; cc < 3; ++cc) g.origin[cc] -= 0.5 * (g.dims[a] - 1) * g.axes[a][cc];
    const HexMesh m = mesh(d, g);
    EXPECT_TRUE(topologicallyValid(m));
    EXPECT_LT(maxBoundaryDistance(m, s), 0.1 * 0.6);
    // interior hexes are the grid's parallelepipeds: positive
    const Topology t = buildTopology(m);
    std::size_t positiveInterior = 0, interior = 0;
    for (std::size_t h = 0; h < m.hexCount(); ++h) {
        bool touches = false;
        for (Index v : m.hexes[h]) touches = touches || t.nodeOnBoundary[v];
        if (touches) continue;
        ++interior;
        positiveInterior += minCornerDeterminant(hexCoords(m, h)) > 0;
    }
    EXPECT_GT(interior, 100u);
    EXPECT_EQ(positiveInterior, interior);
}

TEST(DualContour, MirroredGridStillGivesPositiveHexes) {
    const AnalyticDomain d({sphere({0, 0, 0}, 4.0)});
    Grid g = unitGrid(13, 1.0, {6, -6, -6});
    g.axes[0] = {-1, 0, 0};  // x runs backwards: a left-handed grid
    ASSERT_LT(g.determinant(), 0);
    const HexMesh m = mesh(d, g);
    EXPECT_TRUE(topologicallyValid(m));
    double vol = 0;
    for (std::size_t h = 0; h < m.hexCount(); ++h) vol += hexVolume(hexCoords(m, h));
    EXPECT_GT(vol, 0);
}

TEST(DualContour, TwoMaterialsShareAnInterfaceOfClassifiedNodes) {
    const AnalyticDomain d({box({3, 3, 3}, {9.5, 13, 13}), box({9.5, 3, 3}, {15, 13, 13})});
    const HexMesh m = mesh(d, unitGrid(18));
    EXPECT_TRUE(topologicallyValid(m));
    const Topology t = buildTopology(m);
    EXPECT_GT(t.interfaceQuads.size(), 50u);
    const auto patches = surfacePatches(m, t);
    ASSERT_EQ(patches.size(), 3u);  // boundary of 1, interface 1|2, boundary of 2
    std::size_t curve = 0, surface = 0;
    for (const auto& c : m.nodeClass) {
        curve += c.kind == NodeKind::Curve;
        surface += c.kind == NodeKind::Surface;
    }
    EXPECT_GT(curve, 0u);  // where the interface meets the outer boundary
    EXPECT_GT(surface, 0u);
}

TEST(DualContour, MeshingTheExteriorFillsTheBoxConformally) {
    const AnalyticDomain d({sphere({8, 8, 8}, 4.2)});
    Labels l = sampleLabels(d, unitGrid(17));
    repairNonManifold(l, d);
    ExtractOptions opt;
    opt.meshExterior = true;
    const HexMesh m = dualContourHexes(l, d, opt);
    EXPECT_EQ(m.hexCount(), 17u * 17u * 17u);
    EXPECT_TRUE(topologicallyValid(m));
    const Topology t = buildTopology(m);
    const auto patches = surfacePatches(m, t);
    ASSERT_EQ(patches.size(), 2u);  // the box (material 0's boundary) and the 0|1 interface
    // only hexes touching the sphere may be inverted; the grid hexes away from it are cubes
    for (std::size_t h = 0; h < m.hexCount(); ++h) {
        if (minCornerDeterminant(hexCoords(m, h)) > 0) continue;
        bool touches = false;
        for (Index v : m.hexes[h]) touches = touches || m.nodeClass[v].kind != NodeKind::Interior;
        EXPECT_TRUE(touches) << "hex " << h;
    }
}

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

TEST(DualContour, SameMeshForAnyThreadCount) {
    const AnalyticDomain d({torus({12, 12, 12}, 7, 3.1)});
    HexMesh one;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        one = mesh(d, unitGrid(25));
    }
    const HexMesh many = mesh(d, unitGrid(25));
    EXPECT_EQ(one.hexes, many.hexes);
    EXPECT_EQ(one.nodes, many.nodes);
}

TEST(KeepLargest, DropsSmallerRegionsOfEachMaterialOnly) {
    const AnalyticDomain d({unite(sphere({8, 10, 10}, 5), sphere({17, 10, 10}, 2.2)), sphere({10, 10, 25}, 3)});
    octree::Grid g = unitGrid(31);
    Labels l = sampleLabels(d, g);
    std::size_t small = 0, second = 0;
    for (std::size_t p = 0; p < l.material.size(); ++p) {
        const int i = static_cast<int>(p % 31);
        small += l.material[p] == 1 && i > 14;
        second += l.material[p] == 2;
    }
    ASSERT_GT(small, 0u);
    const std::size_t removed = keepLargestComponents(l);
    EXPECT_EQ(removed, small);
    std::size_t secondAfter = 0;
    for (auto m : l.material) secondAfter += m == 2;
    EXPECT_EQ(secondAfter, second);  // material 2 is one region: untouched
    const auto topo = regionTopology(l);
    ASSERT_EQ(topo.size(), 2u);
    EXPECT_EQ(topo[0].components, 1u);
}

TEST(NonManifoldRepair, RandomMultiMaterialLabelsBecomeValidMeshes) {
    // Random labellings are the worst case for touching regions: every material
    // and every interface between two materials must come out 2-manifold.
    for (unsigned seed = 1; seed <= 6; ++seed) {
        const int n = 9;
        auto v = grid3(n);
        unsigned state = seed * 2654435761u;
        for (int k = 1; k < n - 1; ++k)
            for (int j = 1; j < n - 1; ++j)
                for (int i = 1; i < n - 1; ++i) {
                    state = state * 1664525u + 1013904223u;
                    set(v, n, i, j, k, static_cast<std::int32_t>((state >> 16) % 4));  // 0..3
                }
        const PointSetDomain d({n, n, n}, v);
        Labels l = sampleLabels(d, unitGrid(n));
        repairNonManifold(l, d);
        EXPECT_EQ(countNonManifoldBlocks(l), 0u) << "seed " << seed;
        EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d))) << "seed " << seed;
    }
}

TEST(LbieCellTests, SmoothLargeShapePassesAndThinFeatureFails) {
    // a big ball: coarse cells see at most one crossing per edge
    const AnalyticDomain ball({sphere({16, 16, 16}, 11)});
    EXPECT_EQ(lbieFailures(sampleLabels(ball, unitGrid(33))), 0u);
    // a plate one fine step thick between coarse points: coarse edges across it change material twice
    const AnalyticDomain plate({box({3, 3, 14.6}, {29, 29, 15.4})});
    EXPECT_GT(lbieFailures(sampleLabels(plate, unitGrid(33))), 0u);
}

// Samples d on an n^3 unit grid, repairs it and extracts the hexes (with the
// background out to the grid's box when `exterior`).
static HexMesh repairedAndExtracted(const AnalyticDomain& d, int n, bool exterior) {
    Labels l = sampleLabels(d, unitGrid(n));
    repairNonManifold(l, d);
    ExtractOptions opt;
    opt.meshExterior = exterior;
    return dualContourHexes(l, d, opt);
}

TEST(DualContour, NodeClassesFromTheGridEqualThoseFromTheHexFaces) {
    // dualContourHexes classifies nodes from the grid labels; classifyBoundaryNodes
    // finds them from the hexes' faces. Both must agree: several materials,
    // interfaces, curves where they meet the boundary, and a meshed exterior.
    const AnalyticDomain d({box({3, 3, 3}, {9.5, 13, 13}), box({9.5, 3, 3}, {15, 13, 13}), sphere({9, 8, 8}, 3.3)});
    for (bool exterior : {false, true}) {
        const HexMesh m = repairedAndExtracted(d, 18, exterior);
        HexMesh again = m;
        classifyBoundaryNodes(again);
        EXPECT_EQ(m.surfaces, again.surfaces) << "exterior " << exterior;
        // classifyBoundaryNodes does not name curves (id -1); the grid does
        std::vector<NodeClass> named = m.nodeClass;
        for (auto& c : named)
            if (c.kind == NodeKind::Curve) c.id = -1;
        EXPECT_EQ(named, again.nodeClass) << "exterior " << exterior;
        EXPECT_TRUE(again.curves.empty());
        std::size_t curves = 0;
        for (const auto& c : m.nodeClass) curves += c.kind == NodeKind::Curve;
        EXPECT_GT(curves, 0u);
        EXPECT_GE(m.surfaces.size(), exterior ? 4u : 5u);
    }
}

TEST(DualContour, BoundaryCornersOfCurvedAndThinShapesLieOnTheSurface) {
    // Every corner of a boundary quad within 0.1 grid step of the zero set, on
    // shapes whose QEF minimisers fall off the surface or out of their cells:
    // a small sphere (strong curvature), a thin plate, a thin torus, two balls
    // almost touching, on grids whose points do not sit on the surfaces.
    const std::vector<std::pair<const char*, Sdf>> shapes = {
        {"small sphere", sphere({7.3, 7.1, 6.9}, 2.7)},
        {"thin plate", box({3.2, 3.4, 7.7}, {13.1, 12.6, 8.9})},
        {"thin torus", torus({9.2, 9.1, 8.8}, 5.3, 1.4)},
        {"two balls", unite(sphere({5.6, 8.2, 8.1}, 3.05), sphere({12.3, 8.2, 8.1}, 3.05))}};
    for (const auto& [name, f] : shapes) {
        const AnalyticDomain d({f});
        Labels l = sampleLabels(d, unitGrid(19));
        const Labels fresh = l;
        repairNonManifold(l, d);
        ExtractStats st;
        const HexMesh m = dualContourHexes(l, d, {}, &st);
        EXPECT_TRUE(topologicallyValid(m)) << name;
        const Topology t = buildTopology(m);
        // corners of cells whose labels the repair left alone, including
        // those whose move onto the surface inverts a hex (the mesh keeps them
        // on the surface; their held-back position is only in ExtractStats)
        double worst = 0;
        for (Index v : t.boundaryNodes) {
            const Vec3& x = m.nodes[v];
            const int ci = static_cast<int>(std::floor(x[0])) + 1, cj = static_cast<int>(std::floor(x[1])) + 1,
                      ck = static_cast<int>(std::floor(x[2])) + 1;
            bool changed = false;
            for (int c = 0; c < 8; ++c) {
                const std::size_t p = l.grid.index(ci - 1 + (c & 1), cj - 1 + (c >> 1 & 1), ck - 1 + (c >> 2 & 1));
                changed = changed || l.material[p] != fresh.material[p];
            }
            if (!changed) worst = std::max(worst, std::abs(f(x)));
        }
        EXPECT_LT(worst, 0.1) << name;
        // held-back positions stay in their vertex's cell
        ASSERT_EQ(st.heldBack.size(), st.heldBackAt.size());
        for (std::size_t i = 0; i < st.heldBack.size(); ++i) {
            const Vec3& s = m.nodes[st.heldBack[i]];
            const Vec3& h = st.heldBackAt[i];
            for (int c = 0; c < 3; ++c) EXPECT_EQ(std::floor(s[c]), std::floor(h[c])) << name << " node " << st.heldBack[i];
        }
    }
}

TEST(DualContour, MovesOntoTheSurfaceInvertNoHexTheQefVerticesKeepValid) {
    // Every hex inverted with the held-back positions is inverted with the
    // plain QEF vertices too: a move onto the surface that would invert a hex
    // is held back.
    const std::vector<std::pair<const char*, Sdf>> shapes = {
        {"torus", torus({12.2, 12.1, 11.9}, 7.3, 2.9)},
        {"two balls", unite(sphere({7.6, 10.2, 10.1}, 4.05), sphere({16.3, 10.2, 10.1}, 4.05))},
        {"thin plate", box({3.2, 3.4, 9.7}, {19.1, 18.6, 10.6})}};
    for (const auto& [name, f] : shapes) {
        const AnalyticDomain d({f});
        Labels l = sampleLabels(d, unitGrid(25));
        repairNonManifold(l, d);
        ExtractOptions plain;
        plain.projectVertices = false;
        const HexMesh q = dualContourHexes(l, d, plain);
        ExtractStats st;
        HexMesh m = dualContourHexes(l, d, {}, &st);
        ASSERT_EQ(m.hexes, q.hexes);
        // the mesh as it goes on without a boundary sheet
        for (std::size_t i = 0; i < st.heldBack.size(); ++i) m.nodes[st.heldBack[i]] = st.heldBackAt[i];
        std::size_t invertedMoved = 0, invertedPlain = 0;
        for (std::size_t h = 0; h < m.hexCount(); ++h) {
            const bool inverted = minCornerDeterminant(hexCoords(m, h)) <= 0;
            const bool invertedQef = minCornerDeterminant(hexCoords(q, h)) <= 0;
            invertedMoved += inverted;
            invertedPlain += invertedQef;
            EXPECT_FALSE(inverted && !invertedQef) << name << " hex " << h;
        }
        EXPECT_LE(invertedMoved, invertedPlain) << name;
    }
}

TEST(DualContour, CurveNodesNameTheThreeMaterialsMeetingThere) {
    // Two boxes side by side with a ball across their interface: curves where
    // the interface meets the outside, where the ball meets both boxes, and
    // where the ball meets the outside. A Curve node names the materials of
    // its hexes (and -1 on the outer boundary) when they are three, and no
    // curve (-1) where four meet or where the box around a meshed exterior is one of them.
    const AnalyticDomain d({box({3, 3, 3}, {9.5, 13, 13}), box({9.5, 3, 3}, {15, 13, 13}), sphere({9, 8, 12.2}, 3.3)});
    for (bool exterior : {false, true}) {
        const HexMesh m = repairedAndExtracted(d, 18, exterior);
        const Topology t = buildTopology(m);
        ASSERT_FALSE(m.curves.empty());
        EXPECT_TRUE(std::is_sorted(m.curves.begin(), m.curves.end()));
        std::size_t named = 0, unnamed = 0;
        for (std::size_t v = 0; v < m.nodeCount(); ++v) {
            if (m.nodeClass[v].kind != NodeKind::Curve) continue;
            std::set<std::int32_t> mats;
            for (const Index* h = t.nodeHexes.begin(v); h != t.nodeHexes.end(v); ++h) mats.insert(m.material[*h]);
            if (t.nodeOnBoundary[v]) mats.insert(-1);
            const std::int32_t id = m.nodeClass[v].id;
            const bool box = exterior && mats.count(0) && mats.count(-1);
            if (mats.size() == 3 && !box) {
                ASSERT_GE(id, 0) << "node " << v;
                ASSERT_LT(static_cast<std::size_t>(id), m.curves.size());
                const auto& c = m.curves[static_cast<std::size_t>(id)];
                EXPECT_EQ(mats, std::set<std::int32_t>(c.begin(), c.end())) << "node " << v;
                ++named;
            } else {
                EXPECT_EQ(id, -1) << "node " << v << " among " << mats.size() << " materials";
                ++unnamed;
            }
        }
        EXPECT_GT(named, 10u) << "exterior " << exterior;
        EXPECT_GT(unnamed, 0u) << "exterior " << exterior;  // where the ball meets both boxes and the outside
    }
}

TEST(FillPits, FillsOneCellPitsAndWellsButKeepsCavitiesAndWiderGaps) {
    const int n = 12;
    auto v = solidBlock(n, 2, 9);
    set(v, n, 5, 5, 9, 0);                                           // a pit one cell deep, open at the top
    for (int k = 7; k <= 9; ++k) set(v, n, 3, 3, k, 0);              // a well three cells deep
    set(v, n, 7, 4, 5, 0);                                           // a one-point cavity
    set(v, n, 4, 7, 4, 0), set(v, n, 4, 7, 5, 0);                    // a two-point cavity
    set(v, n, 7, 7, 9, 0), set(v, n, 8, 7, 9, 0);                    // a trench two cells wide
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    const auto before = regionTopology(l);
    const std::size_t filled = fillOneCellPits(l);
    auto at = [&](int i, int j, int k) { return l.material[l.grid.index(i, j, k)]; };
    EXPECT_EQ(filled, 4u);
    EXPECT_EQ(at(5, 5, 9), 1);
    for (int k = 7; k <= 9; ++k) EXPECT_EQ(at(3, 3, k), 1) << k;
    EXPECT_EQ(at(7, 4, 5), 0);
    EXPECT_EQ(at(4, 7, 4), 0);
    EXPECT_EQ(at(4, 7, 5), 0);
    EXPECT_EQ(at(7, 7, 9), 0);
    EXPECT_EQ(at(8, 7, 9), 0);
    EXPECT_EQ(at(5, 5, 10), 0);  // nothing grows above the rim
    // simple points only: components and Euler characteristic (with both cavities) unchanged
    const auto after = regionTopology(l);
    ASSERT_EQ(before.size(), 1u);
    ASSERT_EQ(after.size(), 1u);
    EXPECT_EQ(after[0].components, before[0].components);
    EXPECT_EQ(after[0].euler, before[0].euler);
    EXPECT_EQ(after[0].points, before[0].points + 4);
    EXPECT_EQ(before[0].components, 3u);  // the outer surface and the two cavities
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);
    EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d)));
    EXPECT_EQ(fillOneCellPits(l), 0u);  // a fixpoint
}

// editNearInvertedHexes (the pipeline's retry where hexes stay inverted):
// near the given positions it shaves a one-point bump and fills a one-point
// pit, moves a material's lone point into the material around it, and never
// edits a point whose change would alter a topology (a bridge, a speck, a
// cavity), a frozen point, or twice at one place.
TEST(InvertedHexEdits, ShavesABumpFillsAPitAndNeverChangesTopology) {
    const int n = 14;
    auto v = solidBlock(n, 2, 10);
    set(v, n, 6, 6, 11, 1);   // a one-point bump on the top face
    set(v, n, 4, 4, 10, 0);   // a one-point pit in it
    set(v, n, 8, 8, 6, 0);    // a one-point cavity inside
    const PointSetDomain d({n, n, n}, v);
    const Labels start = sampleLabels(d, unitGrid(n));
    ASSERT_EQ(countNonManifoldBlocks(start), 0u);
    const auto before = regionTopology(start);
    auto at = [](const Labels& l, int i, int j, int k) { return l.material[l.grid.index(i, j, k)]; };

    Labels l = start;
    // two positions at the bump (one edit there), one at the pit, one at the cavity
    const auto edits = editNearInvertedHexes(l, {{6.2, 5.9, 11.3}, {6.0, 6.4, 11.0}, {4.3, 4.1, 9.8}, {8, 8, 6}});
    ASSERT_EQ(edits.size(), 2u);
    EXPECT_EQ(edits[0].point, l.grid.index(6, 6, 11));
    EXPECT_EQ(edits[0].from, 1);
    EXPECT_EQ(edits[0].to, 0);
    EXPECT_EQ(edits[1].point, l.grid.index(4, 4, 10));
    EXPECT_EQ(edits[1].from, 0);
    EXPECT_EQ(edits[1].to, 1);
    EXPECT_EQ(at(l, 6, 6, 11), 0);
    EXPECT_EQ(at(l, 4, 4, 10), 1);
    EXPECT_EQ(at(l, 8, 8, 6), 0);  // filling the cavity would remove a boundary component
    const auto after = regionTopology(l);
    ASSERT_EQ(after.size(), 1u);
    EXPECT_EQ(after[0].components, before[0].components);
    EXPECT_EQ(after[0].euler, before[0].euler);
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);

    // frozen: the bump stays, and nothing else near it is exposed enough
    Labels f = start;
    EXPECT_TRUE(editNearInvertedHexes(f, {{6, 6, 11}}, {f.grid.index(6, 6, 11)}).empty());
    EXPECT_EQ(f.material, start.material);

    // a bridge one point thick between two blocks, and a lone speck: no edit
    auto w = grid3(n);
    for (int k = 2; k <= 10; ++k)
        for (int j = 2; j <= 10; ++j)
            for (int i : {2, 3, 4, 8, 9, 10}) set(w, n, i, j, k);
    for (int i = 5; i <= 7; ++i) set(w, n, i, 6, 6);  // the bridge
    set(w, n, 6, 11, 11);                              // a speck
    const PointSetDomain d2({n, n, n}, w);
    Labels b = sampleLabels(d2, unitGrid(n));
    const Labels bridge = b;
    EXPECT_TRUE(editNearInvertedHexes(b, {{6, 6, 6}, {6, 11, 11}}).empty());
    EXPECT_EQ(b.material, bridge.material);
    // the maximum of own-material face neighbours bounds what counts as exposed
    EXPECT_TRUE(editNearInvertedHexes(l = start, {{6, 6, 11}}, {}, 0).empty());
}

TEST(InvertedHexEdits, AMaterialsLonePointJoinsTheMaterialAroundIt) {
    // materials 1 (x 2..6) and 2 (x 7..11); one point of 2 sticks into 1
    const int n = 14;
    auto v = grid3(n);
    for (int k = 2; k <= 10; ++k)
        for (int j = 2; j <= 10; ++j)
            for (int i = 2; i <= 11; ++i) set(v, n, i, j, k, i <= 6 ? 1 : 2);
    set(v, n, 6, 6, 6, 2);
    const PointSetDomain d({n, n, n}, v);
    Labels l = sampleLabels(d, unitGrid(n));
    const auto before = regionTopology(l);
    const auto edits = editNearInvertedHexes(l, {{6.4, 6, 6}});
    ASSERT_EQ(edits.size(), 1u);
    EXPECT_EQ(edits[0].point, l.grid.index(6, 6, 6));
    EXPECT_EQ(edits[0].from, 2);
    EXPECT_EQ(edits[0].to, 1);
    const auto after = regionTopology(l);
    ASSERT_EQ(after.size(), before.size());
    for (std::size_t m = 0; m < after.size(); ++m) {
        EXPECT_EQ(after[m].components, before[m].components);
        EXPECT_EQ(after[m].euler, before[m].euler);
    }
    EXPECT_EQ(countNonManifoldBlocks(l), 0u);

    // a one-point pocket of background where the two meet: filling it with
    // material 1 keeps material 1's topology (it only touches 1 and 2), but
    // the object's union would lose a cavity, so it stays
    set(v, n, 6, 6, 6, 0);
    const PointSetDomain d2({n, n, n}, v);
    Labels pocket = sampleLabels(d2, unitGrid(n));
    const Labels pocketStart = pocket;
    EXPECT_TRUE(editNearInvertedHexes(pocket, {{6, 6, 6}}).empty());
    EXPECT_EQ(pocket.material, pocketStart.material);
    // positions off the grid or not finite are skipped
    EXPECT_TRUE(editNearInvertedHexes(pocket, {{-5, 6, 6}, {6, 1e300, 6}, {std::nan(""), 6, 6}}).empty());
}

TEST(InvertedHexEdits, RandomLabelsKeepTheirTopologyAndStayManifold) {
    // Blobby random labellings with up to three materials, repaired, then
    // edited at random positions: whatever is edited, every material keeps its
    // components and Euler characteristic, every block stays manifold, every
    // edit lies within one point of a position and had at most two face
    // neighbours of its material, and the mesh extracts valid.
    std::size_t total = 0;
    for (unsigned seed = 1; seed <= 60; ++seed) {
        const int n = 12;
        auto v = grid3(n);
        unsigned state = seed * 2654435761u;
        auto rnd = [&] { return (state = state * 1664525u + 1013904223u) >> 8; };
        const int balls = 3 + static_cast<int>(rnd() % 4);
        std::vector<std::array<double, 5>> c;  // centre, radius, material
        for (int b = 0; b < balls; ++b)
            c.push_back({2.0 + rnd() % 800 / 100.0, 2.0 + rnd() % 800 / 100.0, 2.0 + rnd() % 800 / 100.0,
                         1.0 + rnd() % 250 / 100.0, static_cast<double>(1 + rnd() % (seed % 3 + 1))});
        for (int k = 1; k < n - 1; ++k)
            for (int j = 1; j < n - 1; ++j)
                for (int i = 1; i < n - 1; ++i)
                    for (const auto& b : c)
                        if ((i - b[0]) * (i - b[0]) + (j - b[1]) * (j - b[1]) + (k - b[2]) * (k - b[2]) <= b[3] * b[3])
                            set(v, n, i, j, k, static_cast<std::int32_t>(b[4]));
        const PointSetDomain d({n, n, n}, v);
        Labels l = sampleLabels(d, unitGrid(n));
        repairNonManifold(l, d);
        ASSERT_EQ(countNonManifoldBlocks(l), 0u) << "seed " << seed;
        const Labels start = l;
        const auto before = regionTopology(l);
        auto unionOf = [](Labels u) {
            for (auto& m : u.material) m = m != 0 ? 1 : 0;
            return regionTopology(u);
        };
        const auto unionBefore = unionOf(l);
        std::vector<std::array<double, 3>> at;
        for (int q = 0; q < 12; ++q)
            at.push_back({1.0 + rnd() % 1000 / 100.0, 1.0 + rnd() % 1000 / 100.0, 1.0 + rnd() % 1000 / 100.0});
        const auto edits = editNearInvertedHexes(l, at);
        total += edits.size();
        Labels cur = start;  // the labels as each edit found them (earlier edits of the call applied)
        for (const auto& e : edits) {
            const int i = static_cast<int>(e.point % n), j = static_cast<int>(e.point / n % n),
                      k = static_cast<int>(e.point / n / n);
            EXPECT_EQ(cur.material[e.point], e.from);
            EXPECT_NE(e.from, e.to);
            EXPECT_TRUE(std::any_of(at.begin(), at.end(), [&](const auto& x) {
                return std::abs(std::lround(x[0]) - i) <= 1 && std::abs(std::lround(x[1]) - j) <= 1 &&
                       std::abs(std::lround(x[2]) - k) <= 1;
            })) << "seed " << seed;
            int same = 0;
            for (int a = 0; a < 3; ++a)
                for (int s : {-1, 1}) {
                    std::array<int, 3> q{i, j, k};
                    q[a] += s;
                    same += cur.material[cur.grid.index(q[0], q[1], q[2])] == e.from;
                }
            EXPECT_LE(same, 2) << "seed " << seed;
            cur.material[e.point] = e.to;
        }
        EXPECT_EQ(cur.material, l.material) << "seed " << seed;
        std::size_t changed = 0;
        for (std::size_t p = 0; p < l.material.size(); ++p) changed += l.material[p] != start.material[p];
        EXPECT_EQ(changed, edits.size()) << "seed " << seed;
        EXPECT_EQ(countNonManifoldBlocks(l), 0u) << "seed " << seed;
        const auto after = regionTopology(l);
        ASSERT_EQ(after.size(), before.size()) << "seed " << seed;
        for (std::size_t m = 0; m < after.size(); ++m) {
            EXPECT_EQ(after[m].material, before[m].material) << "seed " << seed;
            EXPECT_EQ(after[m].components, before[m].components) << "seed " << seed << " material " << after[m].material;
            EXPECT_EQ(after[m].euler, before[m].euler) << "seed " << seed << " material " << after[m].material;
        }
        // the object as a whole (and so the background) keeps its topology too
        const auto unionAfter = unionOf(l);
        ASSERT_EQ(unionAfter.size(), unionBefore.size()) << "seed " << seed;
        if (!unionAfter.empty()) {
            EXPECT_EQ(unionAfter[0].components, unionBefore[0].components) << "seed " << seed;
            EXPECT_EQ(unionAfter[0].euler, unionBefore[0].euler) << "seed " << seed;
        }
        EXPECT_TRUE(topologicallyValid(dualContourHexes(l, d))) << "seed " << seed;
    }
    std::cout << "[figures] " << total << " edits over 60 random labellings\n";
    EXPECT_GT(total, 60u);  // the check above is not vacuous
}

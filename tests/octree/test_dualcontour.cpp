// Dual contouring of labelled grids into hexes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <set>

#include "AnalyticDomains.hpp"
#include "LabelGrids.hpp"
#include <tbb/global_control.h>

#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/octree/DualContour.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
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
        // and with the held-back positions none at all (corners and centre):
        // at worst a vertex goes back to its cell's centre, where the hexes
        // are the grid's cubes
        for (std::size_t h = 0; h < m.hexCount(); ++h)
            EXPECT_GT(minJacobianDeterminant(hexCoords(m, h)), 0) << name << " hex " << h;
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

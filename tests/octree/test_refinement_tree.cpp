// The 27-tree's closure and its conformal mesh: random refinements of a
// solid block and the label-change criterion on an analytic sphere.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include <nlohmann/json.hpp>

#include "AnalyticDomains.hpp"
#include "LabelGrids.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/octree/AdaptiveHexes.hpp"
#include "isohex/octree/DualContour.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/RefinementTree.hpp"

using namespace isohex;
using namespace isohex::octree;
using namespace isohex::test;

namespace {

Labels solid(std::array<int, 3> dims, Grid g = {}) {
    g.dims = dims;
    Labels l{g, std::vector<std::int32_t>(g.size(), 1)};
    return l;
}

// Level-l cells flagged with probability p (fixed seed).
std::vector<std::vector<std::uint8_t>> randomRequests(const std::array<int, 3>& points, int top,
                                                      const std::vector<double>& p, unsigned seed) {
    std::mt19937 rng(seed);
    std::vector<std::vector<std::uint8_t>> req(static_cast<std::size_t>(top) + 1);
    int side = 1;
    for (int l = 1; l <= top; ++l) {
        side *= 3;
        std::size_t n = 1;
        for (int c = 0; c < 3; ++c) n *= static_cast<std::size_t>((points[c] + side - 1) / side);
        std::bernoulli_distribution coin(static_cast<std::size_t>(l) < p.size() ? p[static_cast<std::size_t>(l)] : 0.0);
        req[static_cast<std::size_t>(l)].resize(n);
        for (auto& r : req[static_cast<std::size_t>(l)]) r = coin(rng);
    }
    return req;
}

// A mesh of a solid box: valid, positively oriented, conformal (boundary
// quads only on the box, so no hanging node or non-conformal face inside),
// filling the box, leaves graded by at most one level around every node.
void expectConformalBox(const AdaptiveMesh& a, const Vec3& lo, const Vec3& hi) {
    const HexMesh& m = a.mesh;
    const ValidityReport v = validate(m);
    EXPECT_TRUE(v.ok()) << toJson(v).dump();
    double volume = 0;
    for (Index h = 0; h < static_cast<Index>(m.hexCount()); ++h) {
        const HexCoords x = hexCoords(m, h);
        ASSERT_GT(minJacobianDeterminant(x), 0) << "hex " << h;
        volume += hexVolume(x);
    }
    EXPECT_NEAR(volume, (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]), 1e-6 * volume);
    const Topology t = buildTopology(m);
    double area = 0;
    for (Index q : t.boundaryQuads) {
        const auto& n = t.quads[static_cast<std::size_t>(q)].nodes;
        bool onBox = false;
        for (int c = 0; c < 3 && !onBox; ++c)
            for (double side : {lo[c], hi[c]}) {
                bool all = true;
                for (Index i : n) all = all && std::abs(m.nodes[static_cast<std::size_t>(i)][c] - side) < 1e-9;
                onBox = onBox || all;
            }
        ASSERT_TRUE(onBox) << "boundary quad " << q << " inside the box: a hanging node or non-conformal face";
        const Vec3 &p0 = m.nodes[static_cast<std::size_t>(n[0])], &p1 = m.nodes[static_cast<std::size_t>(n[1])],
                   &p2 = m.nodes[static_cast<std::size_t>(n[2])], &p3 = m.nodes[static_cast<std::size_t>(n[3])];
        const Vec3 d1{p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]}, d2{p3[0] - p1[0], p3[1] - p1[1], p3[2] - p1[2]};
        const Vec3 c{d1[1] * d2[2] - d1[2] * d2[1], d1[2] * d2[0] - d1[0] * d2[2], d1[0] * d2[1] - d1[1] * d2[0]};
        area += 0.5 * std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    }
    const double dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
    EXPECT_NEAR(area, 2 * (dx * dy + dy * dz + dz * dx), 1e-6 * area);
    std::vector<int> lowest(m.nodeCount(), 99), highest(m.nodeCount(), -1);
    for (std::size_t h = 0; h < m.hexCount(); ++h)
        for (Index n : m.hexes[h]) {
            lowest[static_cast<std::size_t>(n)] = std::min<int>(lowest[static_cast<std::size_t>(n)], a.hexLevel[h]);
            highest[static_cast<std::size_t>(n)] = std::max<int>(highest[static_cast<std::size_t>(n)], a.hexLevel[h]);
        }
    for (std::size_t n = 0; n < m.nodeCount(); ++n) ASSERT_LE(highest[n] - lowest[n], 1) << "node " << n;
}

}  // namespace

TEST(RefinementTree, RandomRefinementsOfABlockAreConformal) {
    const std::array<int, 3> dims{54, 27, 27};  // two roots of level 3
    const Labels l = solid(dims);
    for (unsigned seed = 1; seed <= 6; ++seed) {
        const RefinementTree tree = closeRefinement(dims, 3, randomRequests(dims, 3, {0, 0.01, 0.05}, seed));
        const AdaptiveMesh a = assembleAdaptive(leafHexes(tree, l), l.grid);
        SCOPED_TRACE(seed);
        expectConformalBox(a, {-0.5, -0.5, -0.5}, {53.5, 26.5, 26.5});
        EXPECT_LT(a.mesh.hexCount(), l.grid.size());
        std::size_t levelsUsed = 0;
        for (std::size_t n : a.hexesPerLevel) levelsUsed += n > 0;
        EXPECT_GE(levelsUsed, 2u);
    }
}

TEST(RefinementTree, MirroredGridStaysPositivelyOriented) {
    Grid g;
    g.axes = {{{-1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
    const std::array<int, 3> dims{27, 27, 27};
    const Labels l = solid(dims, g);
    const RefinementTree tree = closeRefinement(dims, 3, randomRequests(dims, 3, {0, 0.05}, 7));
    const AdaptiveMesh a = assembleAdaptive(leafHexes(tree, l), l.grid);
    expectConformalBox(a, {-26.5, -0.5, -0.5}, {0.5, 26.5, 26.5});
}

TEST(RefinementTree, NoRefinementIsOneHexPerRootAndFullRefinementIsTheUniformGrid) {
    const std::array<int, 3> dims{27, 27, 27};
    const Labels l = solid(dims);
    EXPECT_EQ(assembleAdaptive(leafHexes(closeRefinement(dims, 3, {}), l), l.grid).mesh.hexCount(), 1u);
    std::vector<std::vector<std::uint8_t>> all(2);
    all[1].assign(9 * 9 * 9, 1);
    const AdaptiveMesh a = assembleAdaptive(leafHexes(closeRefinement(dims, 3, all), l), l.grid);
    EXPECT_EQ(a.mesh.hexCount(), l.grid.size());
    expectConformalBox(a, {-0.5, -0.5, -0.5}, {26.5, 26.5, 26.5});
}

TEST(RefinementTree, LabelChangesKeepTheBoundaryAndTheVolumeOfTheUniformMesh) {
    // a box with a spherical bump
    const Sdf s = unite(box({4.3, 4.3, 4.3}, {52.6, 52.6, 40.6}), sphere({28, 28, 40}, 9.2));
    const AnalyticDomain d({s});
    Labels l = sampleLabels(d, unitGrid(57));
    repairNonManifold(l, d);
    const HexMesh uniform = dualContourHexes(l, d);
    const RefinementTree tree = refineAtLabelChanges(l, {});
    const AdaptiveMesh a = coarsenDualMesh(l, tree, uniform);
    const HexMesh& m = a.mesh;
    EXPECT_TRUE(topologicallyValid(m));
    EXPECT_LE(m.hexCount(), uniform.hexCount());
    EXPECT_EQ(tree.requested[1] > 0, true);
    // the same boundary: same boundary quads (as node positions), same volume
    const Topology tu = buildTopology(uniform), ta = buildTopology(m);
    EXPECT_EQ(ta.boundaryQuads.size(), tu.boundaryQuads.size());
    std::vector<Vec3> bu, ba;
    for (Index n : tu.boundaryNodes) bu.push_back(uniform.nodes[static_cast<std::size_t>(n)]);
    for (Index n : ta.boundaryNodes) ba.push_back(m.nodes[static_cast<std::size_t>(n)]);
    std::sort(bu.begin(), bu.end());
    std::sort(ba.begin(), ba.end());
    EXPECT_EQ(ba, bu);
    double vu = 0, va = 0;
    for (Index h = 0; h < static_cast<Index>(uniform.hexCount()); ++h) vu += hexVolume(hexCoords(uniform, h));
    for (Index h = 0; h < static_cast<Index>(m.hexCount()); ++h) va += hexVolume(hexCoords(m, h));
    EXPECT_NEAR(va, vu, 1e-9 * vu);
    // node classes come from the uniform mesh: every boundary node is on the surface
    for (Index n : ta.boundaryNodes) EXPECT_NE(m.nodeClass[static_cast<std::size_t>(n)].kind, NodeKind::Interior);
    // coarse hexes are positively oriented (only boundary hexes of dual contouring may be inverted)
    for (Index h = 0; h < static_cast<Index>(m.hexCount()); ++h) {
        if (a.hexLevel[static_cast<std::size_t>(h)] > 0) {
            EXPECT_GT(minJacobianDeterminant(hexCoords(m, h)), 0);
        }
    }
}

namespace {

// Level-1 requests (a root level of 9 x 9 x 9 cells over 27^3 points) for the
// cells where `refine(i, j, k)` holds.
template <class F>
std::vector<std::vector<std::uint8_t>> levelOneRequests(F refine) {
    std::vector<std::vector<std::uint8_t>> req(2);
    req[1].resize(9 * 9 * 9);
    for (int k = 0; k < 9; ++k)
        for (int j = 0; j < 9; ++j)
            for (int i = 0; i < 9; ++i) req[1][static_cast<std::size_t>((k * 9 + j) * 9 + i)] = refine(i, j, k);
    return req;
}

}  // namespace

TEST(RefinementTree, AnLShapedRefinedRegionKeepsItsCoarseSideWithTwoFaceTemplates) {
    // Refined cells on two adjacent sides (x < 2 or y < 2) of a coarse region:
    // the coarse cells along the region's convex edge see refined neighbours
    // on two adjacent faces (six marked corners) and take the two-face template.
    const std::array<int, 3> dims{27, 27, 27};
    const Labels l = solid(dims);
    const RefinementTree tree = closeRefinement(dims, 1, levelOneRequests([](int i, int j, int) { return i < 2 || j < 2; }));
    const RefinementLevel& L = tree.levels[1];
    int twoFace = 0, plain = 0;
    for (std::size_t c = 0; c < L.refined.size(); ++c) {
        if (L.refined[c]) continue;
        const TemplateChoice t = chooseTemplate(L.marks[c]);
        twoFace += t.action == TemplateChoice::Action::Template && t.kind == TemplateKind::TwoFace;
        plain += t.action == TemplateChoice::Action::Plain;
    }
    EXPECT_EQ(twoFace, 9);  // the column of cells at (2, 2, k)
    EXPECT_GT(plain, 0);
    const AdaptiveMesh a = assembleAdaptive(leafHexes(tree, l), l.grid);
    expectConformalBox(a, {-0.5, -0.5, -0.5}, {26.5, 26.5, 26.5});
    EXPECT_LT(a.mesh.hexCount(), l.grid.size());
}

TEST(RefinementTree, ARefinedShellKeepsACoarseInside) {
    // Every cell of the outer shell refined: without the two-face template the
    // closure refined the whole inside; now the centre stays one hex.
    const std::array<int, 3> dims{27, 27, 27};
    const Labels l = solid(dims);
    const RefinementTree tree = closeRefinement(
        dims, 1, levelOneRequests([](int i, int j, int k) { return std::min({i, j, k}) == 0 || std::max({i, j, k}) == 8; }));
    const RefinementLevel& L = tree.levels[1];
    EXPECT_FALSE(L.refined[L.index(4, 4, 4)]);
    EXPECT_EQ(L.marks[L.index(4, 4, 4)], 0);
    const AdaptiveMesh a = assembleAdaptive(leafHexes(tree, l), l.grid);
    expectConformalBox(a, {-0.5, -0.5, -0.5}, {26.5, 26.5, 26.5});
    EXPECT_LT(a.mesh.hexCount(), l.grid.size());
}

TEST(RefinementTree, LeavesAndHexesAreCountedByHowTheLeafIsCut) {
    // One refined level-1 cell in the middle of 3 x 3 x 3: its 6 face
    // neighbours take the FACE template (31 hexes), its 12 edge neighbours
    // EDGE (17), its 8 corner neighbours VERTEX (7); its own 27 hexes are
    // whole level-0 leaves.
    const std::array<int, 3> dims{9, 9, 9};
    std::vector<std::vector<std::uint8_t>> req(2);
    req[1].assign(27, 0);
    req[1][13] = 1;
    const RefinementTree tree = closeRefinement(dims, 1, req);
    const auto index = [](LeafForm f) { return static_cast<std::size_t>(f); };
    {
        const AdaptiveMesh a = assembleAdaptive(leafHexes(tree, solid(dims)), solid(dims).grid);
        ASSERT_EQ(a.hexesPerForm.size(), 2u);
        ASSERT_EQ(a.leavesPerForm.size(), 2u);
        EXPECT_EQ(a.leavesPerForm[0][index(LeafForm::Whole)], 27u);
        EXPECT_EQ(a.hexesPerForm[0][index(LeafForm::Whole)], 27u);
        const std::array<std::size_t, kLeafForms> leaves{0, 8, 12, 6, 0, 0};
        const std::array<std::size_t, kLeafForms> hexes{0, 8 * 7, 12 * 17, 6 * 31, 0, 0};
        EXPECT_EQ(a.leavesPerForm[1], leaves);
        EXPECT_EQ(a.hexesPerForm[1], hexes);
        EXPECT_EQ(a.hexesPerLevel[1], 8 * 7 + 12 * 17 + 6 * 31u);
    }
    {
        // Points with x >= 6 unlabelled: the slab of level-1 cells there gives
        // no hex (every template hex's centroid lies in it), so its 1 face, 4
        // edge and 4 corner neighbours of the refined cell are not counted.
        Labels l = solid(dims);
        for (int k = 0; k < 9; ++k)
            for (int j = 0; j < 9; ++j)
                for (int i = 6; i < 9; ++i) l.material[l.grid.index(i, j, k)] = 0;
        const AdaptiveMesh a = assembleAdaptive(leafHexes(tree, l), l.grid);
        const std::array<std::size_t, kLeafForms> leaves{0, 4, 8, 5, 0, 0};
        EXPECT_EQ(a.leavesPerForm[1], leaves);
        EXPECT_EQ(a.hexesPerForm[1][index(LeafForm::Face)], 5 * 31u);
    }
}

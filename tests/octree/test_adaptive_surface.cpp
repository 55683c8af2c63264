// The adaptive mesher with coarse leaves on the surface (contourAdaptive):
// analytic shapes through the surface criterion, the assembly, the node
// placement and the check rounds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "AnalyticDomains.hpp"
#include "LabelGrids.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/octree/AdaptiveSurface.hpp"
#include "isohex/octree/DualContour.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"

using namespace isohex;
using namespace isohex::octree;
using namespace isohex::test;

namespace {

struct Outcome {
    HexMesh uniform;
    AdaptiveSurfaceResult adaptive;
};

// The uniform mesh as the pipeline has it (held-back positions applied) and the adaptive one.
Outcome mesh(const Domain& d, const Grid& g, AdaptiveSurfaceSettings s = {}) {
    Labels l = sampleLabels(d, g);
    repairNonManifold(l, d);
    ExtractStats stats;
    Outcome o;
    o.uniform = dualContourHexes(l, d, {}, &stats);
    for (std::size_t i = 0; i < stats.heldBack.size(); ++i) o.uniform.nodes[static_cast<std::size_t>(stats.heldBack[i])] = stats.heldBackAt[i];
    o.adaptive = contourAdaptive(l, d, o.uniform, s);
    return o;
}

double volume(const HexMesh& m) {
    double v = 0;
    for (Index h = 0; h < static_cast<Index>(m.hexCount()); ++h) v += hexVolume(hexCoords(m, h));
    return v;
}

// V - E + F of the boundary quads; also checks that every boundary edge is in two of them.
long boundaryEuler(const HexMesh& m) {
    const Topology t = buildTopology(m);
    std::set<Index> nodes;
    std::vector<std::pair<Index, Index>> edges;
    for (Index q : t.boundaryQuads) {
        const auto& n = t.quads[static_cast<std::size_t>(q)].nodes;
        for (int c = 0; c < 4; ++c) {
            nodes.insert(n[static_cast<std::size_t>(c)]);
            const Index a = n[static_cast<std::size_t>(c)], b = n[static_cast<std::size_t>((c + 1) % 4)];
            edges.emplace_back(std::min(a, b), std::max(a, b));
        }
    }
    std::sort(edges.begin(), edges.end());
    for (std::size_t i = 0; i < edges.size(); i += 2) {
        EXPECT_TRUE(i + 1 < edges.size() && edges[i] == edges[i + 1] && (i + 2 >= edges.size() || edges[i + 2] != edges[i]))
            << "boundary edge " << edges[i].first << "-" << edges[i].second << " not in exactly two boundary quads";
        if (i + 1 >= edges.size() || edges[i] != edges[i + 1]) return 99;
    }
    return static_cast<long>(nodes.size()) - static_cast<long>(edges.size() / 2) + static_cast<long>(t.boundaryQuads.size());
}

// Valid (no inverted hex, no hanging node or non-conformal face), coarser
// than uniform, boundary nodes within `tol` of the surface `f`.
void expectGoodAdaptiveMesh(const Outcome& o, const Sdf& f, double tol, double hexFraction) {
    const HexMesh& m = o.adaptive.mesh.mesh;
    const ValidityReport v = validate(m);
    EXPECT_TRUE(v.ok()) << toJson(v).dump();
    for (Index h = 0; h < static_cast<Index>(m.hexCount()); ++h)
        ASSERT_GT(minJacobianDeterminant(hexCoords(m, h)), 0) << "hex " << h;
    EXPECT_EQ(o.adaptive.unresolved, 0u);
    EXPECT_LT(static_cast<double>(m.hexCount()), hexFraction * static_cast<double>(o.uniform.hexCount()));
    EXPECT_GE(o.adaptive.mesh.hexesPerLevel.size(), 2u);  // coarse leaves
    const Topology t = buildTopology(m);
    double worst = 0;
    for (Index n : t.boundaryNodes) {
        worst = std::max(worst, std::abs(f(m.nodes[static_cast<std::size_t>(n)])));
        EXPECT_EQ(m.nodeClass[static_cast<std::size_t>(n)].kind, NodeKind::Surface);
    }
    // no farther than the deviation check allows, or than the uniform mesh's held-back nodes are
    double uniformWorst = 0;
    const Topology tu = buildTopology(o.uniform);
    for (Index n : tu.boundaryNodes) uniformWorst = std::max(uniformWorst, std::abs(f(o.uniform.nodes[static_cast<std::size_t>(n)])));
    EXPECT_LE(worst, std::max(tol, uniformWorst));
    EXPECT_NEAR(volume(m), volume(o.uniform), 0.02 * volume(o.uniform));
}

}  // namespace

TEST(AdaptiveSurface, ASphereGetsCoarseLeavesOnItsSurface) {
    const Sdf s = sphere({32, 32, 32}, 24.3);
    const Outcome o = mesh(AnalyticDomain({s}), unitGrid(65));
    expectGoodAdaptiveMesh(o, s, 0.5, 0.2);
    EXPECT_EQ(boundaryEuler(o.adaptive.mesh.mesh), 2);
    // some boundary hexes are coarse: a level >= 1 hex with a boundary face
    const HexMesh& m = o.adaptive.mesh.mesh;
    const Topology t = buildTopology(m);
    std::size_t coarseBoundary = 0;
    for (Index q : t.boundaryQuads) coarseBoundary += o.adaptive.mesh.hexLevel[static_cast<std::size_t>(t.quads[static_cast<std::size_t>(q)].hex[0])] > 0;
    EXPECT_GT(coarseBoundary, t.boundaryQuads.size() / 4);
}

TEST(AdaptiveSurface, ATiltedPlaneIsCoarseAndOnTheSurface) {
    // a box whose top face is a plane tilted about two axes
    const Sdf b = box({6.3, 6.3, 6.3}, {56.6, 56.6, 56.6});
    const Sdf s = [b](const Vec3& x) {
        const double n[3] = {0.3, 0.2, 0.933};
        const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        const double plane = (n[0] * (x[0] - 32) + n[1] * (x[1] - 32) + n[2] * (x[2] - 34)) / len;
        return std::max(b(x), plane);
    };
    const Outcome o = mesh(AnalyticDomain({s}), unitGrid(64));
    // the box's sharp edges stay fine, with their transitions, on a grid this small
    expectGoodAdaptiveMesh(o, s, 0.5, 0.85);
    EXPECT_EQ(boundaryEuler(o.adaptive.mesh.mesh), 2);
}

TEST(AdaptiveSurface, AThinPlateIsKept) {
    // a plate 1.6 steps thick: the criterion keeps it at the finest level
    const Sdf s = box({8.2, 8.2, 31.1}, {55.8, 55.8, 32.7});
    const Outcome o = mesh(AnalyticDomain({s}), unitGrid(64));
    const HexMesh& m = o.adaptive.mesh.mesh;
    EXPECT_TRUE(validate(m).ok());
    EXPECT_EQ(boundaryEuler(m), 2);
    EXPECT_NEAR(volume(m), volume(o.uniform), 0.01 * volume(o.uniform));
    EXPECT_LE(m.hexCount(), o.uniform.hexCount());
}

TEST(AdaptiveSurface, ATorusKeepsItsHole) {
    const Sdf s = torus({40, 40, 40}, 24.2, 11.3);
    const Outcome o = mesh(AnalyticDomain({s}), unitGrid(81));
    // a tube 11 steps thick is curved too much for level-2 leaves (the
    // deviation check refines them), so with the transitions it saves little
    expectGoodAdaptiveMesh(o, s, 0.5, 1.05);
    EXPECT_EQ(boundaryEuler(o.adaptive.mesh.mesh), 0);  // genus one
}

TEST(AdaptiveSurface, TheCriterionRefinesThreeLabelsAndHolesButNotAFlatPatch) {
    // 9^3 points: one level-2 cell with its ring
    Grid g = unitGrid(9);
    Labels flat{g, std::vector<std::int32_t>(g.size(), 0)};
    for (int k = 0; k < 4; ++k)
        for (int j = 0; j < 9; ++j)
            for (int i = 0; i < 9; ++i) flat.material[g.index(i, j, k)] = 1;
    EXPECT_EQ(surfaceRequests(flat, 1)[1][13], 0);
    Labels three = flat;
    for (int i = 0; i < 9; ++i) three.material[g.index(i, 4, 4)] = 2;  // a rod of a third label on the plane
    EXPECT_EQ(surfaceRequests(three, 1)[1][13], 1);  // the centre cell (1, 1, 1)
    Labels rod{g, std::vector<std::int32_t>(g.size(), 0)};
    for (int i = 0; i < 9; ++i) rod.material[g.index(i, 4, 4)] = 1;  // a rod through the centre cell
    EXPECT_EQ(surfaceRequests(rod, 1)[1][13], 1);
    Labels speck{g, std::vector<std::int32_t>(g.size(), 0)};
    speck.material[g.index(4, 4, 4)] = 1;  // a speck inside the centre cell
    EXPECT_EQ(surfaceRequests(speck, 1)[1][13], 1);
}

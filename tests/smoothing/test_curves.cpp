// Curve nodes slide along their curve when the projector knows curves
// (SurfaceProjector::hasCurves / projectToCurve), and stay put otherwise.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/Optimize.hpp"
#include "support/Blocks.hpp"

using namespace isohex;
using namespace isohex::smoothing;

namespace {

// Curve 0 is the x axis; it has no surfaces.
struct AxisProjector final : SurfaceProjector {
    bool curves = true;
    Vec3 project(std::int32_t, const Vec3& x) const override { return x; }
    bool hasCurves() const override { return curves; }
    Vec3 projectToCurve(std::int32_t, const Vec3& x) const override { return {x[0], 0.0, 0.0}; }
};

// A 4^3 block whose boundary is fixed except the inner nodes of the edge on
// the x axis, which are curve nodes pushed unevenly along it.
HexMesh blockWithCurve() {
    HexMesh m = isohex::test::makeBlock(4, 4, 4);
    const Topology t = buildTopology(m);
    for (Index v : t.boundaryNodes) m.nodeClass[v] = {NodeKind::Fixed, -1};
    const double xs[3] = {0.45, 1.35, 2.1};
    for (int i = 1; i <= 3; ++i) {
        m.nodeClass[i] = {NodeKind::Curve, 0};  // node (i, 0, 0)
        m.nodes[i] = {xs[i - 1], 0.0, 0.0};
    }
    return m;
}

double spacingError(const HexMesh& m) {
    double e = 0;
    for (int i = 1; i <= 3; ++i) e = std::max(e, std::abs(m.nodes[i][0] - i));
    return e;
}

}  // namespace

TEST(OptimizeCurves, CurveNodesEvenOutAlongTheirCurveAndStayOnIt) {
    HexMesh m = blockWithCurve();
    const double before = spacingError(m);
    AxisProjector p;
    const SmoothingResult r = optimizeMesh(m, &p);
    EXPECT_EQ(r.invertedAfter, 0u);
    EXPECT_LT(spacingError(m), 0.5 * before);
    for (int i = 1; i <= 3; ++i) {
        EXPECT_EQ(m.nodes[i][1], 0.0);
        EXPECT_EQ(m.nodes[i][2], 0.0);
    }
}

TEST(OptimizeCurves, WithoutCurveSupportCurveNodesStayBitIdentical) {
    HexMesh m = blockWithCurve();
    const HexMesh before = m;
    AxisProjector p;
    p.curves = false;
    optimizeMesh(m, &p);
    for (int i = 1; i <= 3; ++i) EXPECT_EQ(m.nodes[i], before.nodes[i]);
}

namespace {

// The bottom face z = 0 is surface 0; curve 0 is the line y = 1.4 on it.
struct BottomLineProjector final : SurfaceProjector {
    Vec3 project(std::int32_t, const Vec3& x) const override { return {x[0], x[1], 0.0}; }
    bool hasCurves() const override { return true; }
    Vec3 projectToCurve(std::int32_t, const Vec3& x) const override { return {x[0], 1.4, 0.0}; }
};

// A 4 x 4 x 2 block whose bottom face carries curve 0 as extraction marks a
// junction that runs between grid rows: two rows of curve nodes, (i, 1, 0)
// moved to y = 1.1, 0.3 from the line, and (i, 2, 0) moved to y = 1.9, 0.5
// from it, for i = 1..3. Every quad between the rows has four nodes of the
// curve. The rest of the bottom is surface 0; every other boundary node is
// fixed.
HexMesh blockWithCurveBand() {
    HexMesh m = isohex::test::makeBlock(4, 4, 2);
    classifyBoundaryNodes(m);
    const Topology t = buildTopology(m);
    for (Index v : t.boundaryNodes) {
        const Vec3& x = m.nodes[static_cast<std::size_t>(v)];
        const bool bottomInside = x[2] == 0 && x[0] > 0 && x[0] < 4 && x[1] > 0 && x[1] < 4;
        m.nodeClass[static_cast<std::size_t>(v)] = bottomInside ? NodeClass{NodeKind::Surface, 0} : NodeClass{NodeKind::Fixed, -1};
    }
    for (int row = 1; row <= 2; ++row)
        for (int i = 1; i <= 3; ++i) {
            m.nodeClass[static_cast<std::size_t>(row * 5 + i)] = {NodeKind::Curve, 0};
            m.nodes[static_cast<std::size_t>(row * 5 + i)][1] = row == 1 ? 1.1 : 1.9;
        }
    m.curves = {{1, 2, 3}};
    return m;
}

}  // namespace

TEST(OptimizeCurves, ABandOfCurveNodesIsThinnedToAChainOnTheCurve) {
    HexMesh m = blockWithCurveBand();
    ASSERT_EQ(m.surfaces.size(), 1u);
    BottomLineProjector p;
    const SmoothingResult r = optimizeMesh(m, &p);
    // The row farther from the line leaves the curve for the bottom surface;
    // the nearer row stays a chain on the curve.
    EXPECT_EQ(r.curveNodesDemoted, 3u);
    for (int i = 1; i <= 3; ++i) {
        const NodeClass far = m.nodeClass[static_cast<std::size_t>(10 + i)];
        const NodeClass near = m.nodeClass[static_cast<std::size_t>(5 + i)];
        EXPECT_EQ(far.kind, NodeKind::Surface) << "node (" << i << ", 2, 0)";
        EXPECT_EQ(far.id, 0);
        EXPECT_EQ(near.kind, NodeKind::Curve) << "node (" << i << ", 1, 0)";
        EXPECT_NEAR(m.nodes[static_cast<std::size_t>(5 + i)][1], 1.4, 1e-9);
        EXPECT_EQ(m.nodes[static_cast<std::size_t>(10 + i)][2], 0.0);
    }
    // No surface quad keeps three nodes of the curve, and the hexes on the
    // former band are well shaped rather than flattened onto the line.
    const Topology t = buildTopology(m);
    for (Index q : t.boundaryQuads) {
        int onCurve = 0;
        for (Index v : t.quads[static_cast<std::size_t>(q)].nodes)
            onCurve += m.nodeClass[static_cast<std::size_t>(v)].kind == NodeKind::Curve;
        EXPECT_LE(onCurve, 2) << "quad " << q;
    }
    EXPECT_EQ(r.invertedAfter, 0u);
    double minSJ = 1;
    for (std::size_t h = 0; h < m.hexCount(); ++h)
        minSJ = std::min(minSJ, scaledJacobian(hexCoords(m, static_cast<Index>(h))));
    EXPECT_GT(minSJ, 0.5);
}

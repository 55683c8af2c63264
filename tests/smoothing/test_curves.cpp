// Curve nodes slide along their curve when the projector knows curves
// (SurfaceProjector::hasCurves / projectToCurve), and stay put otherwise.
#include <cmath>

#include <gtest/gtest.h>

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

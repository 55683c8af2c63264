// The corner metrics' analytic derivatives against finite differences, and
// the cube as the minimum of the node objective.
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "isohex/core/Quality.hpp"
#include "isohex/smoothing/CornerMetrics.hpp"
#include "isohex/smoothing/NodeObjective.hpp"
#include "support/Blocks.hpp"

using namespace isohex;
using namespace isohex::smoothing;

namespace {

// A random corner frame with a clearly positive determinant.
Matrix3 randomFrame(std::mt19937_64& rng) {
    std::uniform_real_distribution<double> u(-0.4, 0.4);
    for (;;) {
        Matrix3 A = Matrix3::Identity();
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) A(i, j) += u(rng);
        if (cornerDeterminant(A) > 0.3) return A;
    }
}

template <class Metric>
double valueAt(const Metric& m, Matrix3 A, int role, const Vector3& d) {
    displaceFrame(A, role, d);
    return m.value(A);
}

template <class Metric>
void expectDerivativesMatchFiniteDifferences(const Metric& metric, const Matrix3& A, double tol) {
    const double h = 1e-5;
    for (int role = 0; role < kCentreRole + 8; ++role) {  // corner roles and the 8 centre roles
        CornerDerivatives cd;
        ASSERT_TRUE(metric.nodeDerivatives(A, role, cd));
        EXPECT_NEAR(cd.value, metric.value(A), 1e-14 * std::abs(cd.value) + 1e-300);
        for (int i = 0; i < 3; ++i) {
            const Vector3 e = Vector3::Unit(i) * h;
            const double fd = (valueAt(metric, A, role, e) - valueAt(metric, A, role, -e)) / (2 * h);
            EXPECT_NEAR(cd.gradient[i], fd, tol * (1 + std::abs(fd))) << "role " << role << " component " << i;
            // Hessian column i from central differences of the analytic gradient.
            Matrix3 Ap = A, Am = A;
            displaceFrame(Ap, role, e);
            displaceFrame(Am, role, -e);
            CornerDerivatives cp, cm;
            ASSERT_TRUE(metric.nodeDerivatives(Ap, role, cp));
            ASSERT_TRUE(metric.nodeDerivatives(Am, role, cm));
            const Vector3 col = (cp.gradient - cm.gradient) / (2 * h);
            for (int j = 0; j < 3; ++j)
                EXPECT_NEAR(cd.hessian(j, i), col[j], tol * (1 + std::abs(col[j])))
                    << "role " << role << " entry " << j << "," << i;
        }
        EXPECT_LT((cd.hessian - cd.hessian.transpose()).norm(), 1e-12 * (1 + cd.hessian.norm()));
    }
}

}  // namespace

TEST(InverseMeanRatio, IsOneForAnOrthonormalCornerAndScaleInvariant) {
    const InverseMeanRatio m;
    EXPECT_DOUBLE_EQ(m.value(Matrix3::Identity()), 1.0);
    EXPECT_NEAR(m.value(2.5 * Matrix3::Identity()), 1.0, 1e-15);
    Matrix3 box = Matrix3::Identity();
    box(0, 0) = 2;
    EXPECT_GT(m.value(box), 1.0);
}

TEST(InverseMeanRatio, IsInfiniteForNonPositiveDeterminant) {
    const InverseMeanRatio m;
    Matrix3 flat = Matrix3::Identity();
    flat(2, 2) = 0;
    EXPECT_EQ(m.value(flat), std::numeric_limits<double>::infinity());
    EXPECT_EQ(m.value(-Matrix3::Identity()), std::numeric_limits<double>::infinity());
    CornerDerivatives cd;
    EXPECT_FALSE(m.nodeDerivatives(flat, 0, cd));
}

TEST(InverseMeanRatio, GradientAndHessianMatchFiniteDifferences) {
    std::mt19937_64 rng(7);
    for (int trial = 0; trial < 20; ++trial) expectDerivativesMatchFiniteDifferences(InverseMeanRatio{}, randomFrame(rng), 1e-6);
}

TEST(InverseMeanRatio, OrthonormalCornerIsAStationaryPoint) {
    for (int role = 0; role < kCentreRole + 8; ++role) {  // corner roles and the 8 centre roles
        CornerDerivatives cd;
        ASSERT_TRUE(InverseMeanRatio{}.nodeDerivatives(Matrix3::Identity(), role, cd));
        EXPECT_LT(cd.gradient.norm(), 1e-15);
        // and a minimum: the Hessian is positive semi-definite
        const Eigen::SelfAdjointEigenSolver<Matrix3> es(cd.hessian);
        EXPECT_GT(es.eigenvalues().minCoeff(), -1e-12);
    }
}

TEST(UntangleBeta, IsKnuppsMeasureWithoutSmoothing) {
    const UntangleBeta m{0.1, 0.0};
    EXPECT_DOUBLE_EQ(m.value(Matrix3::Identity()), 0.0);             // det 1 >= beta
    EXPECT_NEAR(m.value(-Matrix3::Identity()), 2 * (0.1 + 1.0), 1e-15);  // |t| - t with t = -1.1
}

TEST(UntangleBeta, GradientAndHessianMatchFiniteDifferences) {
    std::mt19937_64 rng(11);
    for (int trial = 0; trial < 20; ++trial) {
        const Matrix3 A = randomFrame(rng);
        const double t = cornerDeterminant(A);
        // beta near the determinant so the smoothed kink is exercised
        expectDerivativesMatchFiniteDifferences(UntangleBeta{t * 1.05, 0.2 * t}, A, 1e-6);
        Matrix3 inverted = A;
        inverted.col(0) = -inverted.col(0);
        expectDerivativesMatchFiniteDifferences(UntangleBeta{0.1, 0.05}, inverted, 1e-6);
    }
}

TEST(NodeObjective, InteriorNodeOfACubeGridHasZeroGradient) {
    const HexMesh m = test::makeBlock(2, 2, 2, 0.7);
    const Topology topo = buildTopology(m);
    const Index centre = 13;  // (1,1,1)
    std::vector<CornerTerm> terms(8 * termsPerHex);
    const std::size_t n = gatherCornerTerms(m, topo.nodeHexes, centre, terms.data());
    EXPECT_EQ(n, 40u);  // 8 hexes: 4 corners and the centre each
    NodeObjective<InverseMeanRatio> obj(InverseMeanRatio{}, terms.data(), n);
    Vector3 g;
    Matrix3 H;
    EXPECT_NEAR(obj.derivatives(g, H), 40.0, 1e-12);
    EXPECT_LT(g.norm(), 1e-12);
    const Eigen::SelfAdjointEigenSolver<Matrix3> es(H);
    EXPECT_GT(es.eigenvalues().minCoeff(), 0.0);  // a strict local minimum
    // any small move makes it worse
    for (int i = 0; i < 3; ++i) EXPECT_GT(obj.value(Vector3::Unit(i) * 0.01), 40.0);
}

TEST(NodeObjective, GatheredTermsReproduceTheNodeCorners) {
    // Every term is a corner that contains the node (4 per hex) or the centre
    // frame of one of its hexes; on a unit grid each has determinant 1.
    const HexMesh m = test::makeBlock(3, 2, 1);
    const Topology topo = buildTopology(m);
    std::vector<CornerTerm> terms(8 * termsPerHex);
    for (std::size_t v = 0; v < m.nodeCount(); ++v) {
        const std::size_t n = gatherCornerTerms(m, topo.nodeHexes, static_cast<Index>(v), terms.data());
        EXPECT_EQ(n, 5 * topo.nodeHexes.size(v));
        std::size_t centres = 0;
        for (std::size_t i = 0; i < n; ++i) {
            EXPECT_NEAR(cornerDeterminant(terms[i].A), 1.0, 1e-15);
            centres += terms[i].role >= kCentreRole;
        }
        EXPECT_EQ(centres, topo.nodeHexes.size(v));
    }
}

TEST(InverseMeanRatio, FastInversePowerMatchesLibm) {
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> e(-80.0, 80.0);
    for (int i = 0; i < 100000; ++i) {
        const double t = std::exp2(e(rng));
        const double ref = std::pow(t, -2.0 / 3.0);
        EXPECT_NEAR(inversePowTwoThirds(t), ref, 4e-15 * ref) << t;
    }
}

TEST(NodeObjective, CentreFrameFollowsTheNodeLikeTheHexCentreJacobian) {
    // Moving one node of a hex must change the centre term exactly as
    // recomputing the centre Jacobian of the moved hex does.
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-0.2, 0.2);
    HexMesh m = test::makeBlock(1, 1, 1);
    for (auto& p : m.nodes)
        for (double& c : p) c += u(rng);
    const Topology topo = buildTopology(m);
    std::vector<CornerTerm> terms(termsPerHex);
    for (Index v = 0; v < 8; ++v) {
        const std::size_t n = gatherCornerTerms(m, topo.nodeHexes, v, terms.data());
        ASSERT_EQ(n, 5u);
        const Vector3 d(u(rng), u(rng), u(rng));
        Matrix3 A = terms[4].A;
        displaceFrame(A, terms[4].role, d);
        HexMesh moved = m;
        for (int c = 0; c < 3; ++c) moved.nodes[static_cast<std::size_t>(v)][c] += d[c];
        EXPECT_NEAR(cornerDeterminant(A), centreDeterminant(hexCoords(moved, 0)), 1e-12) << "node " << v;
    }
}

namespace {

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// The scalar definition the four-lane kernels must reproduce: normDet and
// InverseMeanRatio's derivativesFromState / fromNormDet of CornerMetrics.hpp,
// summed term by term (what NodeObjective's loops do).
struct Reference {
    double f = 0;
    Vector3 g = Vector3::Zero();
    Matrix3 H = Matrix3::Zero();
    std::vector<NormDet> st;
};
Reference referenceDerivatives(const std::vector<CornerTerm>& terms) {
    Reference r;
    for (const CornerTerm& t : terms) {
        r.st.push_back(normDet(t.A, t.role));
        CornerDerivatives cd;
        if (!InverseMeanRatio{}.derivativesFromState(r.st.back(), cd)) {
            r.f = std::numeric_limits<double>::infinity();
            return r;
        }
        r.f += cd.value;
        r.g += cd.gradient;
        r.H += cd.hessian;
    }
    return r;
}
double referenceValue(const Reference& r, const Vector3& d) {
    double sum = 0;
    for (const NormDet& st : r.st) {
        const double v =
            InverseMeanRatio{}.fromNormDet(st.n + st.gradN.dot(d) + st.w2 * d.squaredNorm(), st.t + st.gradT.dot(d));
        if (v == std::numeric_limits<double>::infinity()) return v;
        sum += v;
    }
    return sum;
}

// Before derivatives(): each frame displaced by d and evaluated from scratch.
double referenceFrameValue(const std::vector<CornerTerm>& terms, const Vector3& d) {
    double sum = 0;
    for (const CornerTerm& t : terms) {
        Matrix3 A = t.A;
        displaceFrame(A, t.role, d);
        const double v = InverseMeanRatio{}.value(A);
        if (v == std::numeric_limits<double>::infinity()) return v;
        sum += v;
    }
    return sum;
}

}  // namespace

// The four-lane kernels give the scalar code's numbers bit for bit, with AVX2
// and without, for every role, for term counts that leave partial blocks, for
// determinants outside the fast cube root's range, for infeasible terms and
// for nodes with more terms than the lanes hold;
// so the smoother's path (and every mesh) is the same on any processor.
TEST(NodeObjective, FourLaneKernelsAreTheScalarCodeBitForBit) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::uniform_int_distribution<int> roleOf(0, kCentreRole + 7);
    std::uniform_int_distribution<int> countOf(1, 61);
    std::uniform_real_distribution<double> logScale(-7.0, 7.0);
    int infeasible = 0, compared = 0, manyTerms = 0;
    for (const bool avx2 : {false, true}) {
        detail::useAvx2(avx2);
        for (int trial = 0; trial < 3000; ++trial) {
            // every 50th node has more terms than the lanes hold at once
            // (the frame values then go through them in chunks)
            const int drawn = countOf(rng);
            std::vector<CornerTerm> terms(static_cast<std::size_t>(trial % 50 == 1 ? 150 + 3 * drawn : drawn));
            // mostly near-cubes at one scale; sometimes wild frames (inverted
            // ones included) and scales whose determinants leave [1e-18, 1e18]
            const double scale = trial % 7 == 0 ? std::pow(10.0, logScale(rng)) : 1.0 + 0.5 * u(rng);
            const double spread = trial % 5 == 0 ? 1.5 : 0.3;
            for (CornerTerm& t : terms) {
                t.A = Matrix3::Identity();
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j) t.A(i, j) = scale * (t.A(i, j) + spread * u(rng));
                t.role = roleOf(rng);
            }
            const Reference ref = referenceDerivatives(terms);
            NodeObjective<InverseMeanRatio> obj(InverseMeanRatio{}, terms.data(), terms.size());
            {
                // (a shorter move for the many-term nodes, so that they are
                // mostly feasible and the chunks' sums are compared)
                const double reach = terms.size() > 150 ? 0.02 : 0.3;
                const Vector3 d = reach * scale * Vector3(u(rng), u(rng), u(rng));
                const double v = obj.value(d), rv = referenceFrameValue(terms, d);
                ASSERT_TRUE(sameBits(v, rv)) << "trial " << trial << " frames: " << v << " vs " << rv;
                manyTerms += terms.size() > detail::ImrState::kCapacity && std::isfinite(v);
            }
            Vector3 g;
            Matrix3 H;
            const double f = obj.derivatives(g, H);
            ASSERT_TRUE(sameBits(f, ref.f)) << "trial " << trial << " avx2 " << avx2 << ": " << f << " vs " << ref.f;
            if (!std::isfinite(ref.f)) {
                ++infeasible;
                continue;
            }
            for (int i = 0; i < 3; ++i) {
                ASSERT_TRUE(sameBits(g[i], ref.g[i])) << "trial " << trial << " gradient " << i;
                for (int j = 0; j < 3; ++j) ASSERT_TRUE(sameBits(H(i, j), ref.H(i, j))) << "trial " << trial;
            }
            for (int k = 0; k < 4; ++k) {
                const Vector3 d = 0.3 * scale * Vector3(u(rng), u(rng), u(rng)) * (k == 0 ? 0.0 : 1.0);
                const double v = obj.value(d), rv = referenceValue(ref, d);
                ASSERT_TRUE(sameBits(v, rv)) << "trial " << trial << ": " << v << " vs " << rv;
            }
            ++compared;
        }
    }
    detail::useAvx2(true);
    EXPECT_GT(infeasible, 100);  // the barrier's +inf was exercised
    EXPECT_GT(compared, 3000);
    EXPECT_GT(manyTerms, 20);
}

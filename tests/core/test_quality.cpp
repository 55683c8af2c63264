#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/NodeTargets.hpp"
#include "isohex/core/Quality.hpp"
#include "support/Blocks.hpp"

using namespace isohex;

namespace {
HexCoords unitCube() {
    return {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}}};
}
HexCoords scaled(HexCoords x, double sx, double sy, double sz) {
    for (auto& p : x) p = {p[0] * sx, p[1] * sy, p[2] * sz};
    return x;
}
}  // namespace

TEST(Quality, UnitCubeIsPerfect) {
    const HexCoords x = unitCube();
    EXPECT_DOUBLE_EQ(scaledJacobian(x), 1.0);
    EXPECT_DOUBLE_EQ(inverseMeanRatio(x), 1.0);
    EXPECT_DOUBLE_EQ(conditionNumber(x), 1.0);
    EXPECT_DOUBLE_EQ(edgeRatio(x), 1.0);
    EXPECT_DOUBLE_EQ(hexVolume(x), 1.0);
    EXPECT_DOUBLE_EQ(minCornerDeterminant(x), 1.0);
}

TEST(Quality, MirroredCubeIsInvertedWithScaledJacobianMinusOne) {
    HexCoords x = unitCube();
    for (auto& p : x) p[0] = -p[0];
    EXPECT_DOUBLE_EQ(scaledJacobian(x), -1.0);
    EXPECT_TRUE(std::isinf(inverseMeanRatio(x)));
    EXPECT_LT(hexVolume(x), 0);
}

TEST(Quality, ShearGivesTheKnownScaledJacobian) {
    HexCoords x = unitCube();
    for (auto& p : x) p[0] += 0.5 * p[2];
    // corner frame (1,0,0),(0,1,0),(0.5,0,1): det 1 / |(0.5,0,1)| = 1/sqrt(1.25)
    EXPECT_NEAR(scaledJacobian(x), 1.0 / std::sqrt(1.25), 1e-15);
    EXPECT_NEAR(hexVolume(x), 1.0, 1e-14);  // shear keeps volume
}

TEST(Quality, CollapsedHexReturnsVerdictsHugeValue) {
    HexCoords x = unitCube();
    for (int i = 4; i < 8; ++i) x[i] = x[i - 4];  // flat
    EXPECT_EQ(scaledJacobian(x), 1e30);
    EXPECT_EQ(edgeRatio(x), 1e30);
}

TEST(Quality, BoxMeanRatioMatchesClosedForm) {
    // 2 x 1 x 0.5 box: every corner A = diag(2, 1, 0.5), det 1, |A|^2 = 5.25
    const HexCoords x = scaled(unitCube(), 2, 1, 0.5);
    EXPECT_NEAR(inverseMeanRatio(x), 5.25 / 3.0, 1e-14);
    EXPECT_NEAR(1.0 / inverseMeanRatio(x), 0.571, 1e-3);  // Verdict's shape for this box
    EXPECT_DOUBLE_EQ(scaledJacobian(x), 1.0);
    EXPECT_DOUBLE_EQ(edgeRatio(x), 4.0);
    EXPECT_DOUBLE_EQ(hexVolume(x), 1.0);
    // condition of diag(2,1,.5): |A||A^-1| / 3 = sqrt(5.25 * 5.25) / 3
    EXPECT_NEAR(conditionNumber(x), 5.25 / 3.0, 1e-14);
}

TEST(Quality, VolumeOfTrilinearHexMatchesDivergenceTheorem) {
    // A general (non-planar-faced) hex: compare with the volume obtained by
    // integrating x over the bilinear faces with a fine midpoint rule.
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> d(-0.2, 0.2);
    HexCoords x = unitCube();
    for (auto& p : x)
        for (double& c : p) c += d(rng);
    const int n = 400;
    double flux = 0;
    static constexpr int faces[6][4] = {{0, 4, 7, 3}, {1, 2, 6, 5}, {0, 1, 5, 4}, {3, 7, 6, 2}, {0, 3, 2, 1}, {4, 5, 6, 7}};
    for (const auto& f : faces)
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                const double u = (i + 0.5) / n, v = (j + 0.5) / n;
                Vec3 p{}, pu{}, pv{};
                const double w[4] = {(1 - u) * (1 - v), u * (1 - v), u * v, (1 - u) * v};
                const double wu[4] = {-(1 - v), (1 - v), v, -v};
                const double wv[4] = {-(1 - u), -u, u, (1 - u)};
                for (int k = 0; k < 4; ++k)
                    for (int c = 0; c < 3; ++c) {
                        p[c] += w[k] * x[f[k]][c];
                        pu[c] += wu[k] * x[f[k]][c];
                        pv[c] += wv[k] * x[f[k]][c];
                    }
                const double nx = pu[1] * pv[2] - pu[2] * pv[1];
                flux += p[0] * nx / (double(n) * n);
            }
    EXPECT_NEAR(hexVolume(x), flux, 1e-5);
}

TEST(Quality, SummaryCountsAndHistogram) {
    HexMesh m = test::makeBlock(2, 1, 1);
    m.addHex(m.hexes[0]);
    // third hex: mirrored copy of hex 0 (inverted)
    Hex mirrored = m.hexes[0];
    std::swap(mirrored[1], mirrored[3]);
    std::swap(mirrored[5], mirrored[7]);
    m.addHex(mirrored);
    const QualitySummary s = summarize(m, computeQuality(m));
    EXPECT_EQ(s.hexes, 4u);
    EXPECT_EQ(s.inverted, 1u);
    EXPECT_EQ(s.below02, 1u);
    EXPECT_EQ(s.degenerate, 0u);
    EXPECT_DOUBLE_EQ(s.scaledJacobian.min, -1.0);
    EXPECT_DOUBLE_EQ(s.scaledJacobian.max, 1.0);
    EXPECT_EQ(s.histogram[0], 1u);
    EXPECT_EQ(s.histogram[10], 3u);
    const nlohmann::json j = toJson(s);
    EXPECT_EQ(j["scaled_jacobian"]["histogram"]["counts"][10], 3);
    EXPECT_EQ(j["scaled_jacobian"]["histogram"]["edges"].size(), 12u);
    EXPECT_EQ(j["scaled_jacobian"]["inverted"], 1);
}

TEST(Quality, DegenerateHexIsCountedApartAndAsPoor) {
    HexMesh m = test::makeBlock(1, 1, 1);
    for (int i = 4; i < 8; ++i) m.nodes[m.hexes[0][i]] = m.nodes[m.hexes[0][i - 4]];
    const QualitySummary s = summarize(m, computeQuality(m));
    EXPECT_EQ(s.degenerate, 1u);
    EXPECT_EQ(s.below02, 1u);
    EXPECT_EQ(s.scaledJacobian.count, 0u);
}

TEST(Quality, SummaryIsIndependentOfThreadCount) {
    HexMesh m = test::makeBlock(40, 30, 20);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> d(-0.3, 0.3);
    for (auto& p : m.nodes)
        for (double& c : p) c += d(rng);
    QualitySummary one;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        one = summarize(m, computeQuality(m));
    }
    const QualitySummary many = summarize(m, computeQuality(m));
    EXPECT_EQ(one.scaledJacobian.mean, many.scaledJacobian.mean);  // bitwise
    EXPECT_EQ(one.totalVolume, many.totalVolume);
    EXPECT_EQ(one.histogram, many.histogram);
}

// moveTowardsTargets takes a node all the way where its hexes stay valid,
// part of the way where the target would invert one, and never inverts one.
TEST(NodeTargets, MovesAsFarAsTheHexesStayValid) {
    HexMesh m = test::makeBlock(2, 1, 1);  // two unit cubes side by side along x
    // the four nodes of the shared face sit at x = 1
    std::vector<Index> face;
    for (std::size_t v = 0; v < m.nodeCount(); ++v)
        if (m.nodes[v][0] == 1.0) face.push_back(static_cast<Index>(v));
    ASSERT_EQ(face.size(), 4u);
    const Index a = face[0], b = face[1];
    const Vec3 inside = {m.nodes[a][0] + 0.25, m.nodes[a][1], m.nodes[a][2]};  // valid: the face bends a quarter in
    const Vec3 beyond = {m.nodes[b][0] + 1.5, m.nodes[b][1], m.nodes[b][2]};  // past the far face: would invert a hex
    const std::vector<Index> nodes = {a, b};
    const std::vector<Vec3> targets = {inside, beyond};
    const TargetsResult r = moveTowardsTargets(m, nodes, targets);
    EXPECT_EQ(r.reached, 1u);
    EXPECT_EQ(r.partway, 1u);
    EXPECT_EQ(m.nodes[a], inside);
    EXPECT_GT(m.nodes[b][0], 1.0);  // it went some of the way
    EXPECT_LT(m.nodes[b][0], 2.0);
    for (std::size_t h = 0; h < m.hexCount(); ++h) EXPECT_GT(minJacobianDeterminant(hexCoords(m, static_cast<Index>(h))), 0);
    EXPECT_THROW(moveTowardsTargets(m, nodes, std::vector<Vec3>{inside}), Error);
}

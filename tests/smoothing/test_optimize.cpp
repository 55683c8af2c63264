// Whole-mesh behaviour of optimizeMesh / untangle: restoring, untangling,
// never worsening, boundary handling, surface projection and determinism.
#include <cmath>
#include <iostream>
#include <string>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "MeshFixtures.hpp"
#include "Projectors.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/Optimize.hpp"

using namespace isohex;
using namespace isohex::smoothing;
using isohex::test::ballFromBlock;
using isohex::test::makeBlock;
using isohex::test::minScaledJacobian;
using isohex::test::perturbInterior;

namespace {

HexMesh classifiedBlock(int n) {
    HexMesh m = makeBlock(n, n, n);
    classifyBoundaryNodes(m);
    return m;
}

Index nodeAt(int n, int i, int j, int k) { return static_cast<Index>((k * (n + 1) + j) * (n + 1) + i); }

double distance(const Vec3& a, const Vec3& b) { return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]); }

// A ball mesh with one pillow sheet under its surface and jittered interior.
HexMesh pillowedBall(int n, double radius, double jitter, std::uint64_t seed) {
    HexMesh m = ballFromBlock(n, radius);
    pillowAllMaterials(m);
    perturbInterior(m, jitter, seed);
    return m;
}

}  // namespace

// Converge fully (the defaults stop at 1e-4 relative improvement of the
// whole mesh's objective, which a single displaced node barely moves).
SmoothingOptions tight() {
    SmoothingOptions opt;
    opt.relativeTolerance = 1e-12;
    opt.moveTolerance = 1e-8;
    opt.wakeTolerance = 1e-8;
    return opt;
}

TEST(Optimize, DisplacedInteriorNodeReturnsToTheCubePosition) {
    HexMesh m = classifiedBlock(4);
    const Index v = nodeAt(4, 2, 2, 2);
    const Vec3 home = m.nodes[v];
    m.nodes[v] = {home[0] + 0.3, home[1] - 0.2, home[2] + 0.25};
    const SmoothingResult r = optimizeMesh(m, nullptr, tight());
    EXPECT_LT(distance(m.nodes[v], home), 1e-3);
    EXPECT_EQ(r.invertedBefore, 0u);
    EXPECT_EQ(r.invertedAfter, 0u);
    EXPECT_LT(r.objectiveAfter, r.objectiveBefore);
    EXPECT_NEAR(r.objectiveAfter, 1.0, 1e-6);
    EXPECT_TRUE(r.converged);
}

// Only the nodes of hexes that are not cubes start active: one displaced node
// in a block of cubes makes its eight hexes poor, whose 27 nodes (all
// interior) are the first sweep's visits. Later sweeps visit only nodes next
// to a node that moved, and every visit is counted, moved or not.
TEST(Optimize, CountsEveryNodeVisitStartingWithTheNodesOfPoorHexes) {
    HexMesh m = classifiedBlock(4);
    const Index v = nodeAt(4, 2, 2, 2);
    m.nodes[v][0] += 0.3;
    const SmoothingResult r = optimizeMesh(m, nullptr);
    ASSERT_EQ(r.visitHistory.size(), static_cast<std::size_t>(r.sweeps));
    ASSERT_GE(r.sweeps, 1);
    EXPECT_EQ(r.visitHistory[0], 27u);
    std::size_t sum = 0;
    for (std::size_t n : r.visitHistory) sum += n;
    EXPECT_EQ(r.nodeVisits, sum);
    EXPECT_GE(r.nodeVisits, r.nodeUpdates);
    EXPECT_GT(r.nodeUpdates, 0u);
    EXPECT_EQ(r.surfaceNodeVisits, 0u);  // no projector: surface nodes stay where they are
}

TEST(Optimize, CountsSurfaceNodeVisitsApart) {
    HexMesh m = pillowedBall(6, 3.0, 0.05, 5);
    const test::SphereProjector sphere({0, 0, 0}, 3.0);
    const SmoothingResult r = optimizeMesh(m, &sphere);
    EXPECT_GT(r.surfaceNodeVisits, 0u);
    EXPECT_LT(r.surfaceNodeVisits, r.nodeVisits);
    EXPECT_GE(r.nodeVisits, r.nodeUpdates);
}

TEST(Optimize, NodePushedThroughAFaceIsUntangled) {
    HexMesh m = classifiedBlock(4);
    const Index v = nodeAt(4, 2, 2, 2);
    const Vec3 home = m.nodes[v];
    m.nodes[v] = {home[0] + 1.4, home[1] + 0.1, home[2] - 0.1};  // beyond the plane of its x+ neighbours
    const SmoothingResult r = optimizeMesh(m, nullptr, tight());
    EXPECT_GT(r.invertedBefore, 0u);
    EXPECT_GE(r.untangleSweeps, 1);
    EXPECT_EQ(r.invertedAfter, 0u);
    EXPECT_TRUE(r.untangleFailures.empty());
    EXPECT_GT(minScaledJacobian(m), 0.9);
    EXPECT_LT(distance(m.nodes[v], home), 1e-3);
}

TEST(Optimize, UntangleAloneRemovesInversionsWithoutOptimising) {
    HexMesh m = classifiedBlock(4);
    const Index v = nodeAt(4, 2, 2, 2);
    m.nodes[v][2] -= 1.5;
    const SmoothingResult r = untangle(m);
    EXPECT_GT(r.invertedBefore, 0u);
    EXPECT_EQ(r.invertedAfter, 0u);
    EXPECT_EQ(r.sweeps, 0);
}

TEST(Optimize, ReportsHexesThatCannotBeUntangledWithTheirLocation) {
    // One hex with every node on the boundary: nothing may move.
    HexMesh m = makeBlock(1, 1, 1, 2.0, {10, 0, 0});
    classifyBoundaryNodes(m);
    m.nodes[6] = {10.5, 0.5, 0.5};  // the far corner pulled inside: corners invert
    const SmoothingResult r = optimizeMesh(m, nullptr);
    ASSERT_EQ(r.invertedAfter, 1u);
    ASSERT_EQ(r.untangleFailures.size(), 1u);
    EXPECT_EQ(r.untangleFailures[0].hex, 0);
    EXPECT_LE(r.untangleFailures[0].minDeterminant, 0.0);
    EXPECT_GT(r.untangleFailures[0].centroid[0], 10.0);
    EXPECT_LT(r.untangleFailures[0].centroid[0], 12.0);
    EXPECT_EQ(r.nodesMoved, 0u);
}

TEST(Optimize, PillowedBlockWithPerturbedInteriorNeverGetsWorse) {
    HexMesh m = classifiedBlock(5);
    pillowAllMaterials(m);
    perturbInterior(m, 0.15, 42);
    const double sjBefore = minScaledJacobian(m);
    const SmoothingResult r = optimizeMesh(m, nullptr);
    ASSERT_EQ(r.invertedBefore, 0u) << "the perturbation should not invert (test set-up)";
    EXPECT_LE(r.objectiveAfter, r.objectiveBefore);
    ASSERT_FALSE(r.objectiveHistory.empty());
    double previous = r.objectiveBefore;
    for (double f : r.objectiveHistory) {
        EXPECT_LE(f, previous * (1 + 1e-12));
        previous = f;
    }
    EXPECT_EQ(r.invertedAfter, 0u);
    EXPECT_GT(minScaledJacobian(m), sjBefore);
    EXPECT_GT(r.nodesMoved, 0u);
}

TEST(Optimize, PillowedBallWithSurfaceSmoothingNeverGetsWorse) {
    HexMesh m = pillowedBall(6, 3.0, 0.05, 5);
    const double sjBefore = minScaledJacobian(m);
    const test::SphereProjector sphere({0, 0, 0}, 3.0);
    const SmoothingResult r = optimizeMesh(m, &sphere);
    ASSERT_EQ(r.invertedBefore, 0u);
    double previous = r.objectiveBefore;
    for (double f : r.objectiveHistory) {
        EXPECT_LE(f, previous * (1 + 1e-12));
        previous = f;
    }
    EXPECT_LT(r.objectiveAfter, r.objectiveBefore);
    EXPECT_EQ(r.invertedAfter, 0u);
    EXPECT_GT(minScaledJacobian(m), sjBefore);
}

TEST(Optimize, FixBoundaryLeavesEveryNonInteriorNodeBitIdentical) {
    HexMesh m = pillowedBall(5, 2.0, 0.15, 9);
    const HexMesh before = m;
    const test::SphereProjector sphere({0, 0, 0}, 2.0);
    SmoothingOptions opt;
    opt.fixBoundary = true;
    const SmoothingResult r = optimizeMesh(m, &sphere, opt);
    EXPECT_GT(r.nodesMoved, 0u);
    std::size_t interiorMoved = 0;
    for (std::size_t v = 0; v < m.nodeCount(); ++v) {
        if (m.nodeClass[v].kind != NodeKind::Interior) {
            EXPECT_EQ(m.nodes[v], before.nodes[v]) << "node " << v;  // bitwise
        } else if (m.nodes[v] != before.nodes[v]) {
            ++interiorMoved;
        }
    }
    EXPECT_EQ(interiorMoved, r.nodesMoved);
}

TEST(Optimize, CurveAndFixedNodesNeverMove) {
    HexMesh m = pillowedBall(5, 2.0, 0.15, 21);
    // mark a few surface nodes as curve or fixed nodes
    std::vector<std::size_t> pinned;
    for (std::size_t v = 0; v < m.nodeCount() && pinned.size() < 12; ++v)
        if (m.nodeClass[v].kind == NodeKind::Surface && v % 5 == 0) {
            m.nodeClass[v] = pinned.size() % 2 ? NodeClass{NodeKind::Curve, 0} : NodeClass{NodeKind::Fixed, -1};
            pinned.push_back(v);
        }
    // and one interior node fixed
    std::size_t fixedInterior = 0;
    while (m.nodeClass[fixedInterior].kind != NodeKind::Interior) ++fixedInterior;
    m.nodeClass[fixedInterior] = {NodeKind::Fixed, -1};
    pinned.push_back(fixedInterior);
    const HexMesh before = m;
    const test::SphereProjector sphere({0, 0, 0}, 2.0);
    const SmoothingResult r = optimizeMesh(m, &sphere);
    EXPECT_GT(r.nodesMoved, 0u);
    for (std::size_t v : pinned) EXPECT_EQ(m.nodes[v], before.nodes[v]) << "node " << v;
}

TEST(Optimize, SurfaceNodesStayOnTheSphere) {
    HexMesh m = pillowedBall(6, 3.0, 0.15, 3);
    const HexMesh before = m;
    const test::SphereProjector sphere({0, 0, 0}, 3.0);
    const SmoothingResult r = optimizeMesh(m, &sphere);
    std::size_t surfaceMoved = 0;
    for (std::size_t v = 0; v < m.nodeCount(); ++v) {
        if (m.nodeClass[v].kind != NodeKind::Surface) continue;
        EXPECT_LT(sphere.distance(m.nodes[v]), 1e-9) << "node " << v;
        if (m.nodes[v] != before.nodes[v]) ++surfaceMoved;
    }
    EXPECT_GT(surfaceMoved, 0u);  // the surface really was smoothed
    EXPECT_EQ(r.invertedAfter, 0u);
}

TEST(Optimize, SurfaceNodesOnAPlaneStayOnThePlane) {
    // A block whose top face is a plane; its nodes slide within it.
    HexMesh m = makeBlock(4, 4, 2);
    classifyBoundaryNodes(m);
    for (std::size_t v = 0; v < m.nodeCount(); ++v)
        if (m.nodes[v][2] == 2.0 && m.nodes[v][0] > 0 && m.nodes[v][0] < 4 && m.nodes[v][1] > 0 && m.nodes[v][1] < 4)
            m.nodes[v][0] += 0.2 * std::sin(3.0 * static_cast<double>(v));
    // only the top face may move: everything else on the boundary is pinned
    for (std::size_t v = 0; v < m.nodeCount(); ++v)
        if (m.nodeClass[v].kind == NodeKind::Surface && m.nodes[v][2] != 2.0) m.nodeClass[v] = {NodeKind::Fixed, -1};
    const test::PlaneProjector plane({0, 0, 1}, 2.0);
    const SmoothingResult r = optimizeMesh(m, &plane);
    for (std::size_t v = 0; v < m.nodeCount(); ++v) {
        if (m.nodeClass[v].kind == NodeKind::Surface) {
            EXPECT_NEAR(m.nodes[v][2], 2.0, 1e-12);
        }
    }
    EXPECT_LT(r.objectiveAfter, r.objectiveBefore);
    EXPECT_NEAR(r.objectiveAfter, 1.0, 1e-3);
}

TEST(Optimize, OutputIsBitIdenticalForOneAndTwoThreads) {
    const HexMesh start = pillowedBall(7, 3.0, 0.15, 17);
    const test::SphereProjector sphere({0, 0, 0}, 3.0);
    auto run = [&](int threads, HexMesh& m) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
        m = start;
        return optimizeMesh(m, &sphere);
    };
    HexMesh one, two;
    const SmoothingResult r1 = run(1, one);
    const SmoothingResult r2 = run(2, two);
    ASSERT_EQ(one.nodes.size(), two.nodes.size());
    for (std::size_t v = 0; v < one.nodeCount(); ++v) ASSERT_EQ(one.nodes[v], two.nodes[v]) << "node " << v;
    EXPECT_EQ(r1.sweeps, r2.sweeps);
    EXPECT_EQ(r1.nodeUpdates, r2.nodeUpdates);
    EXPECT_EQ(r1.visitHistory, r2.visitHistory);
    EXPECT_EQ(r1.surfaceNodeVisits, r2.surfaceNodeVisits);
    EXPECT_EQ(r1.objectiveHistory, r2.objectiveHistory);
    EXPECT_EQ(r1.objectiveAfter, r2.objectiveAfter);
    EXPECT_GT(r1.nodeUpdates, 0u);
}

TEST(Optimize, UntanglingIsBitIdenticalForOneAndTwoThreads) {
    HexMesh start = classifiedBlock(6);
    for (int k : {2, 4})
        for (int j : {2, 4}) start.nodes[nodeAt(6, 3, j, k)][0] += 1.3;
    auto run = [&](int threads, HexMesh& m) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
        m = start;
        return optimizeMesh(m, nullptr);
    };
    HexMesh one, two;
    const SmoothingResult r1 = run(1, one);
    const SmoothingResult r2 = run(2, two);
    EXPECT_GT(r1.invertedBefore, 0u);
    EXPECT_EQ(r1.invertedAfter, 0u);
    for (std::size_t v = 0; v < one.nodeCount(); ++v) ASSERT_EQ(one.nodes[v], two.nodes[v]) << "node " << v;
}

TEST(Optimize, VoxelBallWithSurfaceUntanglingIsBitIdenticalForOneAndTwoThreads) {
    // Folded pillow hexes under a surface: the untangler moves interior and
    // surface nodes before the optimiser runs.
    const double radius = 7.5;
    HexMesh start = test::voxelBall(radius);
    pillowAllMaterials(start);
    perturbInterior(start, 0.45, 77);  // enough to fold some pillow hexes
    const test::SphereProjector sphere({0, 0, 0}, radius);
    auto run = [&](int threads, HexMesh& m) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
        m = start;
        return optimizeMesh(m, &sphere);
    };
    HexMesh one, two;
    const SmoothingResult r1 = run(1, one);
    const SmoothingResult r2 = run(2, two);
    EXPECT_GT(r1.invertedBefore, 0u);
    EXPECT_EQ(r1.invertedAfter, 0u);
    EXPECT_GT(minScaledJacobian(one), 0.2);
    for (std::size_t v = 0; v < one.nodeCount(); ++v) {
        ASSERT_EQ(one.nodes[v], two.nodes[v]) << "node " << v;
        if (one.nodeClass[v].kind == NodeKind::Surface) {
            EXPECT_LT(sphere.distance(one.nodes[v]), 1e-9);
        }
    }
    EXPECT_EQ(r1.untangleSweeps, r2.untangleSweeps);
    std::cout << "[ info ] voxel ball r=" << radius << ": " << one.hexCount() << " hexes, inverted " << r1.invertedBefore
              << " -> " << r1.invertedAfter << ", min scaled Jacobian " << minScaledJacobian(one) << "\n";
}

TEST(Optimize, ProgressReportsItsPhasesEndingAtOne) {
    HexMesh m = classifiedBlock(4);
    m.nodes[nodeAt(4, 2, 2, 2)][1] += 1.4;
    std::vector<std::pair<std::string, double>> calls;
    optimizeMesh(m, nullptr, {}, [&](std::string_view stage, double f) { calls.emplace_back(std::string(stage), f); });
    ASSERT_FALSE(calls.empty());
    bool sawUntangle = false;
    for (const auto& [stage, f] : calls) {
        EXPECT_TRUE(stage == "setup" || stage == "untangle" || stage == "mean_ratio") << stage;
        EXPECT_GE(f, 0.0);
        EXPECT_LE(f, 1.0);
        sawUntangle |= stage == "untangle";
    }
    EXPECT_TRUE(sawUntangle);
    EXPECT_EQ(calls.back().first, "mean_ratio");
    EXPECT_EQ(calls.back().second, 1.0);
}

TEST(Optimize, UnclassifiedBoundaryNodesDoNotMove) {
    HexMesh m = makeBlock(3, 3, 3);  // every node Interior, none classified
    m.nodes[nodeAt(3, 1, 1, 1)][0] += 0.3;
    const HexMesh before = m;
    optimizeMesh(m, nullptr);
    const Topology topo = buildTopology(m);
    for (Index v : topo.boundaryNodes) EXPECT_EQ(m.nodes[v], before.nodes[v]);
}

TEST(Optimize, RejectsASurfaceIdTheMeshDoesNotHave) {
    HexMesh m = classifiedBlock(2);
    m.nodeClass[0] = {NodeKind::Surface, 5};
    EXPECT_THROW(optimizeMesh(m, nullptr), Error);
}

// The seed's thesis on the smallest example: with the boundary fixed, hexes
// owning three faces of a curved surface cannot be repaired by moving interior
// nodes; after one pillow sheet they can.
TEST(Optimize, PillowingTheNonFundamentalBallGivesBetterElementsAfterSmoothing) {
    SmoothingOptions opt;
    opt.fixBoundary = true;
    HexMesh plain = ballFromBlock(6, 3.0);
    HexMesh pillowed = plain;
    pillowAllMaterials(pillowed);
    optimizeMesh(plain, nullptr, opt);
    const SmoothingResult r = optimizeMesh(pillowed, nullptr, opt);
    const double sjPlain = minScaledJacobian(plain), sjPillowed = minScaledJacobian(pillowed);
    EXPECT_EQ(r.invertedAfter, 0u);
    EXPECT_LT(sjPlain, 0.3);  // the corner hexes' boundary corners are beyond repair
    EXPECT_GT(sjPillowed, sjPlain + 0.1);
    std::cout << "[ info ] min scaled Jacobian after smoothing: without pillow " << sjPlain << ", with pillow "
              << sjPillowed << "\n";
}

TEST(Optimize, HexInvertedOnlyAtItsCentreIsSeenAndUntangled) {
    // Eight positive corners and a negative centre Jacobian: VTK and
    // validate() call this hex inverted, so the smoother must too.
    HexMesh m = classifiedBlock(3);
    const double shape[8][3] = {{-0.62, 0.33, -1.5}, {-0.29, -0.44, -2.49}, {0.24, -0.41, -1.09}, {0.8, 0.16, -1.83},
                                {0.05, -1.11, 0.42}, {0.13, -0.14, -0.04}, {0.2, 0.58, -0.2}, {-0.42, -0.61, 0.44}};
    Index centreHex = kNone;
    for (std::size_t h = 0; h < m.hexCount(); ++h) {
        bool inner = true;
        for (Index v : m.hexes[h]) inner = inner && m.nodeClass[static_cast<std::size_t>(v)].kind == NodeKind::Interior;
        if (inner) centreHex = static_cast<Index>(h);
    }
    ASSERT_NE(centreHex, kNone);
    for (int i = 0; i < 8; ++i) {
        Vec3& p = m.nodes[static_cast<std::size_t>(m.hexes[static_cast<std::size_t>(centreHex)][i])];
        p = {1.5 + 0.3 * shape[i][0], 1.5 + 0.3 * shape[i][1], 1.5 + 0.3 * (shape[i][2] + 0.9)};
    }
    const HexCoords x = hexCoords(m, centreHex);
    ASSERT_GT(minCornerDeterminant(x), 0.0);
    ASSERT_LT(centreDeterminant(x), 0.0);
    std::size_t inverted = 0;
    meanObjective(m, &inverted);
    EXPECT_GE(inverted, 1u);
    const SmoothingResult r = optimizeMesh(m, nullptr);
    EXPECT_EQ(r.invertedAfter, 0u);
    for (std::size_t h = 0; h < m.hexCount(); ++h)
        EXPECT_GT(minJacobianDeterminant(hexCoords(m, static_cast<Index>(h))), 0.0) << "hex " << h;
}

namespace {
// One layer of 3x3 hexes whose four inner top nodes sit on the plane
// z = -0.1, below the fixed bottom nodes at z = 0 (everything else is fixed):
// every hex is inverted and no move within the plane can help.
HexMesh foldedLayer() {
    HexMesh m = makeBlock(3, 3, 1);
    classifyBoundaryNodes(m);
    for (std::size_t v = 0; v < m.nodeCount(); ++v) {
        const bool innerTop = m.nodes[v][2] == 1.0 && m.nodes[v][0] > 0 && m.nodes[v][0] < 3 &&
                              m.nodes[v][1] > 0 && m.nodes[v][1] < 3;
        if (innerTop) m.nodes[v][2] = -0.1;
        else m.nodeClass[v] = {NodeKind::Fixed, -1};
    }
    return m;
}
}  // namespace

TEST(Optimize, SurfaceFoldIsUntangledByReleasingItsNodesWithinTheirBound) {
    const test::PlaneProjector plane({0, 0, 1}, -0.1);
    HexMesh locked = foldedLayer();
    SmoothingOptions keep;
    keep.releaseSurfaceToUntangle = false;
    const SmoothingResult r0 = optimizeMesh(locked, &plane, keep);
    EXPECT_EQ(r0.invertedBefore, 9u);
    EXPECT_EQ(r0.invertedAfter, 9u);  // tangential moves cannot open it
    EXPECT_EQ(r0.surfaceNodesReleased, 0u);

    HexMesh m = foldedLayer();
    const HexMesh start = m;
    SmoothingOptions opt;
    const SmoothingResult r = optimizeMesh(m, &plane, opt);
    EXPECT_EQ(r.invertedAfter, 0u);
    EXPECT_GT(r.surfaceNodesReleased, 0u);
    std::size_t off = 0;
    for (std::size_t v = 0; v < m.nodeCount(); ++v) {
        if (start.nodeClass[v].kind != NodeKind::Surface) continue;
        // at most releasePasses x releaseDistance local edge lengths, measured
        // when the release began (edges are at most 1 long here)
        EXPECT_LE(distance(m.nodes[v], start.nodes[v]), opt.releasePasses * opt.releaseDistance * 1.0) << "node " << v;
        off += std::abs(m.nodes[v][2] + 0.1) > 1e-9;
    }
    EXPECT_EQ(off, r.surfaceNodesReleased);  // the report counts exactly the nodes left off the plane
}

namespace {

// Per node, the mean length of its edges (each edge of the mesh once), as
// the untangler measures its travel bound.
std::vector<double> meanEdgeLengths(const HexMesh& m) {
    const Topology topo = buildTopology(m);
    std::vector<double> sum(m.nodeCount(), 0.0);
    std::vector<int> count(m.nodeCount(), 0);
    for (const auto& e : topo.edges) {
        const double l = distance(m.nodes[static_cast<std::size_t>(e[0])], m.nodes[static_cast<std::size_t>(e[1])]);
        for (Index u : e) {
            sum[static_cast<std::size_t>(u)] += l;
            ++count[static_cast<std::size_t>(u)];
        }
    }
    for (std::size_t v = 0; v < sum.size(); ++v) sum[v] /= count[v];
    return sum;
}

}  // namespace

// Knupp's target grows with the edges a node stretches, so without a bound
// a node can keep chasing it; untangling must keep every node within
// untangleMaxTravel of its starting mean edge lengths from where it started.
TEST(Optimize, UntanglingKeepsEveryNodeWithinItsTravelBound) {
    HexMesh start = classifiedBlock(4);
    const Index v = nodeAt(4, 2, 2, 2);
    start.nodes[v][0] += 1.4;  // through the plane of its x+ neighbours
    const std::vector<double> length = meanEdgeLengths(start);

    // With the default bound the pushed node goes back most of the way.
    HexMesh free = start;
    const SmoothingResult rf = untangle(free);
    ASSERT_EQ(rf.invertedAfter, 0u);
    const double bound = 0.25;
    ASSERT_GT(distance(free.nodes[v], start.nodes[v]), 2 * bound * length[v]);

    SmoothingOptions opt;
    opt.untangleMaxTravel = bound;
    HexMesh capped = start;
    const SmoothingResult rc = untangle(capped, opt);
    EXPECT_GT(rc.nodesMoved, 0u);
    EXPECT_GT(distance(capped.nodes[v], start.nodes[v]), 0.0);
    for (std::size_t u = 0; u < capped.nodeCount(); ++u)
        EXPECT_LE(distance(capped.nodes[u], start.nodes[u]), bound * length[u] * (1 + 1e-12)) << "node " << u;
}

TEST(Optimize, RejectsOutOfRangeOptionsNamingThemAndLeavesTheMeshAlone) {
    HexMesh m = classifiedBlock(3);
    m.nodes[nodeAt(3, 1, 1, 1)][2] -= 1.5;  // inverted: smoothing would move it
    const HexMesh before = m;
    auto rejected = [&](auto change, const std::string& name) {
        SmoothingOptions opt;
        change(opt);
        try {
            optimizeMesh(m, nullptr, opt);
            ADD_FAILURE() << name << " accepted";
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
        }
        EXPECT_THROW(untangle(m, opt), Error) << name;
        EXPECT_EQ(m.nodes, before.nodes) << name;
    };
    const double nan = std::nan("");
    rejected([&](SmoothingOptions& o) { o.untangleMaxTravel = nan; }, "untangleMaxTravel");
    rejected([&](SmoothingOptions& o) { o.untangleMaxTravel = 0; }, "untangleMaxTravel");
    rejected([&](SmoothingOptions& o) { o.untangleMaxTravel = -2; }, "untangleMaxTravel");
    rejected([&](SmoothingOptions& o) { o.maxSweeps = -1; }, "maxSweeps");
    rejected([&](SmoothingOptions& o) { o.relativeTolerance = nan; }, "relativeTolerance");
    rejected([&](SmoothingOptions& o) { o.wakeTolerance = -0.1; }, "wakeTolerance");
    rejected([&](SmoothingOptions& o) { o.newton.maxStep = 0; }, "newton.maxStep");
    rejected([&](SmoothingOptions& o) { o.releaseDistance = INFINITY; }, "releaseDistance");

    // No bound at all is a valid choice.
    SmoothingOptions unbounded;
    unbounded.untangleMaxTravel = INFINITY;
    EXPECT_EQ(optimizeMesh(m, nullptr, unbounded).invertedAfter, 0u);
}

// The pipeline builds the topology once for the optimiser and the worst-hex
// pass; handing it in must change nothing, and a topology of another mesh
// must be refused before any node moves.
TEST(Optimize, AGivenTopologyGivesTheSameResultAndOneOfAnotherMeshIsRefused) {
    const HexMesh start = pillowedBall(6, 3.0, 0.3, 7);
    const test::SphereProjector sphere({0, 0, 0}, 3.0);
    HexMesh own = start, given = start;
    const SmoothingResult a = optimizeMesh(own, &sphere);
    const Topology topo = buildTopology(given);
    const SmoothingResult b = optimizeMesh(given, &sphere, {}, {}, &topo);
    ASSERT_GT(a.nodesMoved, 0u);
    EXPECT_EQ(own.nodes, given.nodes);
    EXPECT_EQ(a.sweeps, b.sweeps);

    HexMesh other = start;
    const Topology wrong = buildTopology(classifiedBlock(2));
    EXPECT_THROW(optimizeMesh(other, &sphere, {}, {}, &wrong), Error);
    EXPECT_EQ(other.nodes, start.nodes);
}

// The optimiser keeps each hex's inverse mean ratio and inverted flag and
// re-evaluates only hexes around moved nodes; the figures it reports at the
// end must still be those of the mesh it leaves, through untangling rounds,
// undone rounds, the surface release and the return to the surface.
TEST(Optimize, ReportedFiguresAreThoseOfTheMeshItLeaves) {
    const double radius = 7.5;
    const test::SphereProjector sphere({0, 0, 0}, radius);
    const test::PlaneProjector plane({0, 0, 1}, -0.1);
    struct Case {
        const char* name;
        HexMesh mesh;
        const SurfaceProjector* projector;
        SmoothingOptions opt;
    };
    std::vector<Case> cases;
    {
        HexMesh ball = test::voxelBall(radius);
        pillowAllMaterials(ball);
        perturbInterior(ball, 0.45, 77);
        cases.push_back({"voxel ball", std::move(ball), &sphere, {}});
    }
    cases.push_back({"folded layer, released", foldedLayer(), &plane, {}});
    {
        SmoothingOptions keep;
        keep.releaseSurfaceToUntangle = false;
        cases.push_back({"folded layer, kept on the plane", foldedLayer(), &plane, keep});
    }
    {
        HexMesh block = classifiedBlock(6);
        perturbInterior(block, 0.8, 5);
        cases.push_back({"shaken block", std::move(block), nullptr, {}});
    }
    for (Case& c : cases) {
        const SmoothingResult r = optimizeMesh(c.mesh, c.projector, c.opt);
        std::size_t inverted = 0;
        EXPECT_EQ(r.objectiveAfter, meanObjective(c.mesh, &inverted)) << c.name;
        EXPECT_EQ(r.invertedAfter, inverted) << c.name;
        EXPECT_EQ(r.untangleFailures.size(), inverted) << c.name;
        std::size_t byCorner = 0;
        for (std::size_t h = 0; h < c.mesh.hexCount(); ++h)
            byCorner += !(minJacobianDeterminant(hexCoords(c.mesh, static_cast<Index>(h))) > 0);
        EXPECT_EQ(r.invertedAfter, byCorner) << c.name;
        std::cout << "[ info ] " << c.name << ": inverted " << r.invertedBefore << " -> " << r.invertedAfter
                  << ", untangling sweeps " << r.untangleSweeps << "\n";
    }
}

// Timing on ~1M-hex pillowed meshes. Skipped unless ISOHEX_BENCH is set
// (it takes tens of seconds); run as
//   ISOHEX_BENCH=1 smoothing_tests --gtest_filter='SmoothingBenchmark.*'
#include <chrono>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>

#include <gtest/gtest.h>

#include "MeshFixtures.hpp"
#include "Projectors.hpp"
#include "isohex/smoothing/Optimize.hpp"

using namespace isohex;
using namespace isohex::smoothing;

namespace {

bool benchEnabled() { return std::getenv("ISOHEX_BENCH") != nullptr; }

void runAndReport(const char* name, HexMesh& m, const SurfaceProjector* projector) {
    const auto t0 = std::chrono::steady_clock::now();
    const double sjBefore = test::minScaledJacobian(m);
    SmoothingOptions opt;
    if (const char* e = std::getenv("ISOHEX_BENCH_MOVETOL")) opt.moveTolerance = std::atof(e);
    if (const char* e = std::getenv("ISOHEX_BENCH_NEWTON")) opt.newton.maxIterations = std::atoi(e);
    if (const char* e = std::getenv("ISOHEX_BENCH_RELTOL")) opt.relativeTolerance = std::atof(e);
    if (const char* e = std::getenv("ISOHEX_BENCH_MINSTEP")) opt.newton.minStep = std::atof(e);
    const SmoothingResult r = optimizeMesh(m, projector, opt);
    const double sjAfter = test::minScaledJacobian(m);
    std::cout << "[ bench ] " << name << ": " << m.hexCount() << " hexes, " << m.nodeCount() << " nodes ("
              << r.movableNodes << " movable, " << r.colours << " colours)\n"
              << "          optimizeMesh " << r.seconds << " s (set-up " << r.setupSeconds << " s, untangle "
              << r.untangleSeconds << " s, " << r.untangleSweeps << " untangle sweeps), "
              << r.sweeps << " sweeps, " << r.nodeUpdates << " node updates, " << r.nodesMoved << " nodes moved, "
              << (r.converged ? "converged" : "hit maxSweeps") << "\n"
              << "          mean inverse mean ratio " << r.objectiveBefore << " -> " << r.objectiveAfter
              << ", inverted " << r.invertedBefore << " -> " << r.invertedAfter << ", min scaled Jacobian "
              << sjBefore << " -> " << sjAfter << " (wall incl. SJ " << 
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s)\n";
    {
        const std::vector<double> sj = scaledJacobians(m);
        std::vector<std::size_t> order(sj.size());
        for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
        std::partial_sort(order.begin(), order.begin() + 5, order.end(), [&](auto a, auto b) { return sj[a] < sj[b]; });
        for (int k = 0; k < 5; ++k) {
            const Hex& h = m.hexes[order[k]];
            int surf = 0;
            for (Index v : h) surf += m.nodeClass[v].kind != NodeKind::Interior;
            std::cout << "          worst hex " << order[k] << " SJ " << sj[order[k]] << " surface nodes " << surf << "\n";
        }
    }
    std::cout << "          objective per sweep:";
    for (double f : r.objectiveHistory) std::cout << ' ' << f;
    std::cout << "\n";
    EXPECT_EQ(r.invertedAfter, 0u);
    EXPECT_LE(r.objectiveAfter, r.objectiveBefore);
}

}  // namespace

TEST(SmoothingBenchmark, VoxelBallPillowed) {
    if (!benchEnabled()) GTEST_SKIP() << "set ISOHEX_BENCH=1 to run";
    const double radius = 60.5;
    HexMesh m = test::voxelBall(radius);
    pillowAllMaterials(m);
    const test::SphereProjector sphere({0, 0, 0}, radius);
    runAndReport("voxel ball, boundary on the sphere, pillowed", m, &sphere);
}

TEST(SmoothingBenchmark, WholeBallPillowedAndJittered) {
    if (!benchEnabled()) GTEST_SKIP() << "set ISOHEX_BENCH=1 to run";
    HexMesh m = test::ballFromBlock(96, 48.0);
    pillowAllMaterials(m);
    test::perturbInterior(m, 0.05, 1);
    const test::SphereProjector sphere({0, 0, 0}, 48.0);
    runAndReport("ball (every hex distorted), pillowed, jittered", m, &sphere);
}

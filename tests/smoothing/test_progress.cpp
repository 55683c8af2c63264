// The optimiser's progress: the sweeps' estimate (sweepProgress) and what
// optimizeMesh and raiseWorstHexes report while they run, on a pillowed ball.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include "MeshFixtures.hpp"
#include "Projectors.hpp"
#include "isohex/core/Pillow.hpp"
#include "isohex/smoothing/Optimize.hpp"
#include "isohex/smoothing/SweepProgress.hpp"
#include "isohex/smoothing/WorstHexes.hpp"

using namespace isohex;
using isohex::smoothing::sweepProgress;

namespace {

// Every call, per phase name, in order.
struct Calls {
    std::vector<std::string> order;  // phase names as they first appear
    std::map<std::string, std::vector<double>> fractions;
    Progress callback() {
        return [this](std::string_view phase, double f) {
            const std::string name(phase);
            if (!fractions.count(name)) order.push_back(name);
            fractions[name].push_back(f);
        };
    }
};

bool nonDecreasing(const std::vector<double>& v) {
    for (std::size_t i = 1; i < v.size(); ++i)
        if (v[i] < v[i - 1]) return false;
    return true;
}

}  // namespace

TEST(SweepProgress, FirstSweepsCountAgainstThePrior) {
    EXPECT_EQ(sweepProgress({}), 0.0);
    EXPECT_EQ(sweepProgress({0}), 0.0);
    EXPECT_DOUBLE_EQ(sweepProgress({1000}), 1.0 / smoothing::kPriorSweeps);
    EXPECT_DOUBLE_EQ(sweepProgress({1000, 1000}), 2.0 / smoothing::kPriorSweeps);
    // Visits that grow (the active set spreading) stay on the prior.
    EXPECT_DOUBLE_EQ(sweepProgress({1000, 1100, 1150}), 3250.0 / 9000.0);
}

// Falling visits: the geometric tail takes over once it leaves less than
// the prior (after 1000, 500 the tail is 500 more: 1500 of 2000).
TEST(SweepProgress, FallingVisitsUseTheirGeometricTail) {
    EXPECT_DOUBLE_EQ(sweepProgress({1000, 500}), 0.75);
    EXPECT_DOUBLE_EQ(sweepProgress({1000, 500, 250}), 1750.0 / 2000.0);
}

// ch2bet at 2 mm (bench/RESULTS.md, "The optimiser's work": the visits of
// sweeps 0-8, and the 154,428 of sweeps 9-15 split as they fall): after
// every sweep the estimate is within 0.1 of the fraction of the phase's
// visits done, and below 0.99 until the sweeps end.
TEST(SweepProgress, FollowsTheVisitsOfARealRun) {
    const std::vector<std::size_t> visits = {180003, 192989, 189571, 181786, 172175, 158724, 137699, 109668,
                                             79795,  50000,  35000,  25000,  18000,  13000,  8428,   5000};
    double total = 0;
    for (std::size_t v : visits) total += static_cast<double>(v);
    double done = 0;
    for (std::size_t k = 1; k <= visits.size(); ++k) {
        done += static_cast<double>(visits[k - 1]);
        const double f = sweepProgress(std::vector<std::size_t>(visits.begin(), visits.begin() + k));
        EXPECT_NEAR(f, done / total, 0.05) << "after sweep " << k;
        EXPECT_LE(f, 0.99);
    }
}

// The optimiser reports its set-up, untangling and sweeps, each phase's
// fractions never going back within a run of it and the sweeps ending at 1;
// the worst-hex pass reports its own, ending at 1.
TEST(OptimizerProgress, PhasesReportRisingFractionsThatEndAtOne) {
    const test::SphereProjector sphere({0, 0, 0}, 3.0);
    HexMesh m = test::ballFromBlock(6, sphere.radius);
    pillowAllMaterials(m);
    Calls calls;
    smoothing::optimizeMesh(m, &sphere, {}, calls.callback());
    ASSERT_FALSE(calls.order.empty());
    EXPECT_EQ(calls.order.front(), "setup");
    ASSERT_TRUE(calls.fractions.count("mean_ratio"));
    // the first run of sweeps: one call per sweep, then the end (later runs,
    // after an untangling round, count again from their own start)
    std::vector<double> sweeps = calls.fractions["mean_ratio"];
    sweeps.resize(static_cast<std::size_t>(std::find(sweeps.begin(), sweeps.end(), 1.0) - sweeps.begin()) + 1);
    EXPECT_GE(sweeps.size(), 3u);
    EXPECT_TRUE(nonDecreasing(sweeps));
    EXPECT_GT(sweeps.front(), 0.0);
    EXPECT_LT(sweeps.front(), 0.5);  // not the end after the first sweep

    smoothing::WorstHexOptions o;
    o.target = 0.95;  // above what the ball's sheet reaches: every kind of round runs
    Calls worst;
    smoothing::raiseWorstHexes(m, &sphere, o, nullptr, worst.callback());
    ASSERT_EQ(worst.order, std::vector<std::string>{"worst_hexes"});
    const std::vector<double>& rounds = worst.fractions["worst_hexes"];
    EXPECT_TRUE(nonDecreasing(rounds));
    EXPECT_EQ(rounds.back(), 1.0);
    // a max-min round and a mean round each reported within their part of the pass
    EXPECT_TRUE(std::any_of(rounds.begin(), rounds.end(), [](double f) { return f > 0 && f < 0.3; }));
    EXPECT_TRUE(std::any_of(rounds.begin(), rounds.end(), [](double f) { return f > 0.4 && f < 0.95; }));
}

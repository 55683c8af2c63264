// PhasedProgress: one stage's fraction from its phases', never going back.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "isohex/core/PhasedProgress.hpp"

namespace isohex {
namespace {

struct Heard {
    std::vector<std::string> stages;
    std::vector<double> fractions;
    Progress callback() {
        return [this](std::string_view stage, double f) {
            stages.emplace_back(stage);
            fractions.push_back(f);
        };
    }
};

TEST(PhasedProgress, MapsEachPhaseIntoItsShareInOrder) {
    Heard heard;
    PhasedProgress p(heard.callback(), "optimize", {{"a", 1}, {"b", 3}});
    p.report("a", 0.5);  // half of the first quarter
    p.report("a", 1.0);
    p.report("b", 0.5);  // a quarter plus half of three quarters
    p.report("b", 1.0);
    EXPECT_EQ(heard.fractions, (std::vector<double>{0.125, 0.25, 0.625, 1.0}));
    EXPECT_EQ(heard.stages, std::vector<std::string>(4, "optimize"));
}

// A phase that starts its own count again, or an earlier phase that runs
// again after a later one, holds the fraction instead of taking it back.
TEST(PhasedProgress, NeverGoesBack) {
    Heard heard;
    PhasedProgress p(heard.callback(), "s", {{"untangle", 1}, {"sweeps", 1}});
    p.report("untangle", 1.0);
    p.report("sweeps", 0.5);
    p.report("untangle", 0.5);  // a second untangling round
    p.report("sweeps", 0.25);   // a second, shorter run of sweeps
    p.report("sweeps", 0.75);
    EXPECT_EQ(heard.fractions, (std::vector<double>{0.5, 0.75, 0.875}));
    EXPECT_DOUBLE_EQ(p.fraction(), 0.875);
}

// A skipped phase is passed over; a phase not in the list, a NaN and
// fractions out of [0, 1] change nothing or are clamped.
TEST(PhasedProgress, SkipsPhasesAndIgnoresUnknownNames) {
    Heard heard;
    PhasedProgress p(heard.callback(), "s", {{"a", 1}, {"b", 1}, {"c", 2}});
    p.report("c", 0.5);  // a and b did not run
    p.report("elsewhere", 1.0);
    p.report("c", std::nan(""));
    p.report("c", 7.0);
    EXPECT_EQ(heard.fractions, (std::vector<double>{0.75, 1.0}));
}

TEST(PhasedProgress, WorksWithoutAnOutputAndThroughItsCallback) {
    PhasedProgress quiet({}, "s", {{"a", 1}});
    quiet.callback()("a", 0.4);
    EXPECT_DOUBLE_EQ(quiet.fraction(), 0.4);
}

}  // namespace
}  // namespace isohex

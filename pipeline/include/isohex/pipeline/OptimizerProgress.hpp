#pragma once
// The optimize stage's progress from the optimiser's phases: PhasedProgress
// with each phase's share of the stage's time, measured on ch2bet at 1.25 mm
// (set-up 4%, untangling under 1%, mean-ratio sweeps 62%, worst-hex pass
// 32%); the second max-min target's pass, where it runs, gets the rest. The
// sink hears one fraction that never goes down.
#include <string_view>
#include <utility>
#include <vector>

#include "isohex/core/PhasedProgress.hpp"
#include "isohex/pipeline/StageSink.hpp"

namespace isohex::pipeline {

enum class WorstHexesInStage { No, Yes };

inline PhasedProgress optimizerProgress(StageSink& sink, WorstHexesInStage worst) {
    std::vector<ProgressPhase> phases = {{"setup", 4}, {"untangle", 2}, {"mean_ratio", 60}};
    if (worst == WorstHexesInStage::Yes) {
        phases.push_back({"worst_hexes", 30});
        phases.push_back({"stretch", 4});
    }
    return PhasedProgress([&sink](std::string_view, double f) { sink.progress(f); }, "optimize", std::move(phases));
}

}  // namespace isohex::pipeline

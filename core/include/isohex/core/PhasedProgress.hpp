#pragma once
// One stage's progress from the progress of its phases (the optimiser's
// untangling, mean-ratio sweeps and worst-hex rounds): each phase owns a
// share of the stage, in the order given; a phase's own fraction maps into
// its share. The stage's fraction passed on never goes down: a phase that
// ends early or is skipped jumps to the next one's share, and a phase that
// runs again after a later one (the untangling's second round) holds the
// fraction where it is.
#include <string>
#include <string_view>
#include <vector>

#include "isohex/core/Progress.hpp"

namespace isohex {

struct ProgressPhase {
    std::string name;  // as the phase names itself in its Progress calls
    double share = 1;  // of the stage, relative to the other phases' (> 0)
};

class PhasedProgress {
public:
    // `out` may be empty (then nothing is passed on); it gets `stage` as its name.
    PhasedProgress(Progress out, std::string stage, std::vector<ProgressPhase> phases);
    // callback() refers to this object: it stays where it is made.
    PhasedProgress(const PhasedProgress&) = delete;
    PhasedProgress& operator=(const PhasedProgress&) = delete;
    // `fraction` of `phase` done; a phase not in the list is ignored.
    void report(std::string_view phase, double fraction);
    // A Progress that reports here (valid while this object lives).
    Progress callback();
    // The stage's fraction passed on so far.
    double fraction() const { return shown_; }

private:
    Progress out_;
    std::string stage_;
    std::vector<ProgressPhase> phases_;
    std::vector<double> starts_;  // each phase's start, as a fraction of the stage
    double shown_ = 0;
};

}  // namespace isohex

#include "isohex/core/PhasedProgress.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace isohex {

PhasedProgress::PhasedProgress(Progress out, std::string stage, std::vector<ProgressPhase> phases)
    : out_(std::move(out)), stage_(std::move(stage)), phases_(std::move(phases)) {
    double total = 0;
    for (const ProgressPhase& p : phases_) total += std::max(0.0, p.share);
    double start = 0;
    for (ProgressPhase& p : phases_) {
        starts_.push_back(start);
        p.share = total > 0 ? std::max(0.0, p.share) / total : 0.0;
        start += p.share;
    }
}

void PhasedProgress::report(std::string_view phase, double fraction) {
    const auto it = std::find_if(phases_.begin(), phases_.end(), [&](const ProgressPhase& p) { return p.name == phase; });
    if (it == phases_.end()) return;
    const auto i = static_cast<std::size_t>(it - phases_.begin());
    const double f = std::isfinite(fraction) ? std::clamp(fraction, 0.0, 1.0) : 0.0;
    const double at = std::min(1.0, starts_[i] + it->share * f);
    if (!(at > shown_)) return;
    shown_ = at;
    if (out_) out_(stage_, shown_);
}

Progress PhasedProgress::callback() {
    return [this](std::string_view phase, double fraction) { report(phase, fraction); };
}

}  // namespace isohex

#include "isohex/smoothing/SweepProgress.hpp"

#include <algorithm>

namespace isohex::smoothing {

double sweepProgress(const std::vector<std::size_t>& visitsPerSweep) {
    if (visitsPerSweep.empty()) return 0;
    double done = 0;
    for (std::size_t v : visitsPerSweep) done += static_cast<double>(v);
    if (!(done > 0)) return 0;
    const double first = static_cast<double>(visitsPerSweep.front());
    const double last = static_cast<double>(visitsPerSweep.back());
    const double prior = kPriorSweeps * first;
    // Past the prior, about one more sweep like the last.
    double left = done < prior ? prior - done : last;
    if (visitsPerSweep.size() >= 2) {
        const double before = static_cast<double>(visitsPerSweep[visitsPerSweep.size() - 2]);
        const double ratio = before > 0 ? last / before : 1.0;
        if (ratio < 1) left = std::min(left, last * ratio / (1 - ratio));
    }
    return std::min(0.99, done / (done + left));
}

}  // namespace isohex::smoothing

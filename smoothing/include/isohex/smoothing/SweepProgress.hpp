#pragma once
// How far the mean-ratio sweeps are, for the progress bar. They run until
// their active set empties, so their number is not known in advance; the
// estimate comes from the visits of the sweeps so far: a prior of
// kPriorSweeps sweeps of the first sweep's size (the bench inputs take 7 to 9
// such sweeps' worth of visits: bench/RESULTS.md, "The optimiser's work"),
// and, once the visits fall from sweep to sweep, the geometric tail of that
// fall, whichever leaves less.
#include <cstddef>
#include <vector>

namespace isohex::smoothing {

inline constexpr double kPriorSweeps = 9;

// The fraction of the sweeps' visits done after the sweeps whose visits are
// given (in order), in [0, 0.99]; 0 for none. It is an estimate: the caller
// reports 1 when the sweeps end.
double sweepProgress(const std::vector<std::size_t>& visitsPerSweep);

}  // namespace isohex::smoothing

#pragma once
// The number of worker threads for the rest of the process (--threads N).
// Results do not depend on it: the libraries' parallel loops and reductions
// are deterministic whatever the thread count.
namespace isohex::cli {

// Limits TBB to `threads` workers from now on (tbb::global_control, kept for
// the life of the process); 0 or less keeps TBB's default (all cores).
void applyThreads(int threads);

}  // namespace isohex::cli

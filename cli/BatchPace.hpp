#pragma once
// The pace of a batch of jobs (isohex batch, mesh with several inputs): after
// each job that ran, how many are left to run and the time they will take at
// the mean time per job so far, for the user who meshes hundreds of scans in
// one cluster job. Jobs skipped as up to date are not counted.
#include <cstddef>
#include <optional>
#include <string>

namespace isohex::cli {

class BatchPace {
public:
    // `toRun`: the jobs the batch will run (not up to date).
    explicit BatchPace(std::size_t toRun) : toRun_(toRun) {}
    // A job ran (ok, failed or below the minimum quality) in `seconds`.
    void jobRan(double seconds);
    std::size_t ran() const { return ran_; }
    std::size_t left() const { return toRun_ > ran_ ? toRun_ - ran_ : 0; }
    double elapsedSeconds() const { return seconds_; }
    // Seconds the jobs left will take at the mean pace; none before the first job or after the last.
    std::optional<double> etaSeconds() const;
    // "3 of 12 jobs run in 2.5 min; about 7.5 min left at this pace"
    std::string line() const;

private:
    std::size_t toRun_ = 0, ran_ = 0;
    double seconds_ = 0;
};

}  // namespace isohex::cli

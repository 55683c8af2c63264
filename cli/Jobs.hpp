#pragma once
// One meshing job (input -> outputs + report) and running many of them:
// continue past failures, skip up-to-date outputs, print a summary table.
#include <string>
#include <vector>

#include "ErrorText.hpp"
#include "MeshOptions.hpp"

namespace isohex::cli {

struct Job {
    std::string input;
    std::vector<std::string> outputs;
    std::string report;  // optional JSON report path
    std::string plot;    // optional SVG histogram path
    MeshArgs args;
};

struct JobResult {
    std::string input;
    std::string status;  // "ok", "failed", "skipped", "below" (--min-quality not met)
    std::string message;
    bool written = true;  // the outputs were written ("below" without --allow-below: none)
    std::size_t hexes = 0;
    double minScaledJacobian = 0;
    double meanScaledJacobian = 0;
    std::size_t inverted = 0;
    std::size_t below02 = 0;
    double seconds = 0;
};

// Every file `job` writes, in the order it writes them: meshes, plot, report.
std::vector<std::string> filesOf(const Job& job);

// Runs the pipeline and writes the outputs. Throws isohex::Error on failure
// (after which no output of the job is half-written: each file is atomic).
JobResult runJob(const Job& job, ProgressSink& sink);

// runJob(job, sink) in a child process of its own (cli/Isolate.hpp). Throws
// isohex::Error (also for a crashed or killed child), std::bad_alloc or
// std::runtime_error (an internal error) as runJob would.
JobResult runJobIsolated(const Job& job, ProgressSink& sink);

// Every file a command will write, checked before any work: not named twice,
// not a folder, in a folder that exists, not one of the inputs, and not an
// existing file unless force. Throws isohex::Error naming the path; returns,
// per output, whether it existed (so a failed job removes only what it made).
std::vector<bool> checkOutputPaths(const std::vector<std::string>& outputs, const std::vector<std::string>& inputs,
                                   bool force);

// Outputs that exist and are newer than the input, so a rerun can skip the job.
bool upToDate(const Job& job);
// The file name of `input` without its extension(s): "ct.nii.gz" -> "ct".
std::string stemOf(const std::string& input);

// What runJobs counted.
struct JobsOutcome {
    std::size_t failed = 0;        // errors
    std::size_t belowQuality = 0;  // meshes left below --min-quality
    // kExitError if a job failed, else kExitBelowQuality if one stayed below, else kExitOk.
    int exitCode() const;
};

// Runs every job (skipping up-to-date ones unless force), printing a summary
// table to stdout. After a job finds its disk full, the later jobs that
// write to that disk fail at once (cli/FullDisks.hpp).
// A failed job's message names the settings the user can change the `names`
// way (the flags of `mesh`, the manifest columns of `batch`).
JobsOutcome runJobs(const std::vector<Job>& jobs, bool force, ProgressSink::Mode mode, SettingNames names);

}  // namespace isohex::cli

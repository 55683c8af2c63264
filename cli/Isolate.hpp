#pragma once
// A meshing job (and the work of compare, quality, convert, smooth and
// insert-sheet) in a child process of its own.
//
// The libraries that read scans do not all check what they read: OpenVDB
// crashes on a .vdb whose compressed grid data is damaged (segmentation
// fault, or glibc aborting on a corrupted heap), and the kernel's
// out-of-memory killer ends a process without a word. Either used to end
// `isohex batch` at that input, so the later inputs of a run over hundreds
// of scans were never meshed, and a single `isohex mesh` printed only the
// shell's "Segmentation fault". Each job now runs in a forked child; the
// parent waits, takes the child's result (or its error, rethrown as the same
// kind), and turns a child killed by a signal into an error that names the
// input, the stage it was in and what to do. Outputs the job created and its
// temporaries are removed, as for any failed job.
//
// The parent never runs the pipeline itself, so it has no TBB worker threads
// when it forks (its only other threads are log4cplus's idle ones, started
// when OpenVDB's library loads, which the child never uses). If the fork
// fails the job fails with that reason rather than running in the parent.
// ISOHEX_ISOLATE=0 runs jobs in the process itself (for a debugger).
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "Jobs.hpp"
#include "Progress.hpp"

namespace isohex::cli {

// work() in a child process, as described above: returns what it returned
// (JSON, sent over a pipe), rethrows its error as the same kind, and throws
// isohex::Error naming `input` and the stage when the child dies without a
// result; `files` are the outputs work() writes (those it created, and its
// temporaries, are removed then).
nlohmann::json runIsolated(const std::string& input, const std::vector<std::string>& files,
                           const std::function<nlohmann::json()>& work);

// runJob(job, sink) in a child process, as described above. Throws
// isohex::Error (also for a crashed or killed child), std::bad_alloc or
// std::runtime_error (an internal error) as runJob would.
JobResult runJobIsolated(const Job& job, ProgressSink& sink);

// Called when a stage begins (ProgressSink::begin): inside an isolated job
// it records the stage for the parent's message. It also serves the tests'
// fault injection: with ISOHEX_TEST_CRASH=<stage> the process raises SIGSEGV
// when that stage begins (ISOHEX_TEST_CRASH=<stage>:kill raises SIGKILL);
// a suffix @<text> limits it to jobs whose input path (or the path
// nowReading names) contains the text. The handling of a crashing library is then tested without depending
// on one library's bug.
void stageBegins(std::string_view stage);

// A command that reads its files itself says which one it is reading: the
// "load" stage begins, a crash names that file, and ISOHEX_TEST_CRASH's
// @<text> is matched against it.
void nowReading(const std::string& file);

}  // namespace isohex::cli

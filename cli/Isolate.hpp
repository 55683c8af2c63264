#pragma once
// A meshing job (cli/Jobs.hpp runs each through it), and the work of
// compare, quality, convert, smooth and insert-sheet, in a child process of
// its own.
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

namespace isohex::cli {

// work() in a child process, as described above: returns what it returned
// (JSON, sent over a pipe), rethrows its error as the same kind, and throws
// isohex::Error naming `input` and the stage when the child dies without a
// result; `files` are the outputs work() writes (those it created, and its
// temporaries, are removed then).
nlohmann::json runIsolated(const std::string& input, const std::vector<std::string>& files,
                           const std::function<nlohmann::json()>& work);

// " (under an address-space limit of N MB, ulimit -v)" when the process
// has such a limit, else "": what out-of-memory messages add.
std::string memoryLimitText();

// Messages travel between the processes as byte arrays: a file name need
// not be UTF-8, and JSON strings would replace such bytes.
nlohmann::json bytesOf(const std::string& s);
std::string textOf(const nlohmann::json& bytes);

}  // namespace isohex::cli

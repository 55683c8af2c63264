#pragma once
// The options of a whole run, not of one mesh: --threads, --quiet,
// --log-json, --force. Every command that has them declares them here, so
// they read the same everywhere; a batch manifest refuses them as columns.
#include <initializer_list>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "Progress.hpp"

namespace isohex::cli {

enum class RunOption { Threads, Quiet, LogJson, Force };

struct RunArgs {
    int threads = 0;
    bool quiet = false;
    bool logJson = false;
    bool force = false;
    ProgressSink::Mode progressMode() const {
        return logJson ? ProgressSink::Mode::Json : quiet ? ProgressSink::Mode::Quiet : ProgressSink::Mode::Auto;
    }
};

// Declares `which` run options on `cmd`, in that order.
void addRunOptions(CLI::App* cmd, RunArgs& a,
                   std::initializer_list<RunOption> which = {RunOption::Threads, RunOption::Quiet,
                                                             RunOption::LogJson, RunOption::Force});

// The flag of a run option named as a manifest column would be ("threads",
// "q", "log_json": lower case, '_' for '-', no dashes), e.g. "--log-json";
// nothing if `name` is not a run option.
std::optional<std::string> runOptionFlag(const std::string& name);

// The flag of `which`, e.g. "--force".
std::string flagOf(RunOption which);

}  // namespace isohex::cli

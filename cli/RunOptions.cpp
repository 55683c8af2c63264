#include "RunOptions.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace isohex::cli {

namespace {

struct RunOptionRow {
    RunOption id;
    const char* name;   // the long flag without dashes
    const char* alias;  // a one-letter flag, or ""
    const char* help;
};

const RunOptionRow kRows[] = {
    {RunOption::Threads, "threads", "", "Worker threads (default: all cores); results do not depend on it"},
    {RunOption::Quiet, "quiet", "q", "No progress output (warnings and errors still print)"},
    {RunOption::LogJson, "log-json", "", "Progress and messages as one JSON object per line on stderr"},
    {RunOption::Force, "force", "", "Overwrite existing output files"},
};

// --threads: a whole number from 1 to 1024, said as the mesh options say
// their ranges (NaN and infinities too).
CLI::Validator threadCount() {
    return CLI::Validator(
        [](const std::string& v) {
            char* end = nullptr;
            const double x = std::strtod(v.c_str(), &end);
            const bool ok = !v.empty() && end == v.c_str() + v.size() && x >= 1 && x <= 1024 && x == std::floor(x);
            return ok ? std::string() : "--threads must be a whole number between 1 and 1024 (got '" + v + "')";
        },
        "", "1..1024");
}

const RunOptionRow& row(RunOption id) {
    return *std::find_if(std::begin(kRows), std::end(kRows), [&](const RunOptionRow& r) { return r.id == id; });
}

std::string flagNames(const RunOptionRow& r) {
    return (*r.alias ? "-" + std::string(r.alias) + "," : std::string()) + "--" + r.name;
}

}  // namespace

std::string flagOf(RunOption which) { return "--" + std::string(row(which).name); }

void addRunOptions(CLI::App* cmd, RunArgs& a, std::initializer_list<RunOption> which) {
    for (RunOption id : which) {
        const RunOptionRow& r = row(id);
        switch (id) {
            case RunOption::Threads:
                cmd->add_option(flagNames(r), a.threads, r.help)->check(threadCount());
                break;
            case RunOption::Quiet: cmd->add_flag(flagNames(r), a.quiet, r.help); break;
            case RunOption::LogJson: cmd->add_flag(flagNames(r), a.logJson, r.help); break;
            case RunOption::Force: cmd->add_flag(flagNames(r), a.force, r.help); break;
        }
    }
}

std::optional<std::string> runOptionFlag(const std::string& name) {
    for (const RunOptionRow& r : kRows) {
        std::string column = r.name;
        std::replace(column.begin(), column.end(), '-', '_');
        if (name == column || name == r.alias) return "--" + std::string(r.name);
    }
    return std::nullopt;
}

}  // namespace isohex::cli

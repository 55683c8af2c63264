// isohex batch MANIFEST: mesh every job listed in a CSV or JSON-lines file
// (cli/Manifest.hpp). The jobs run through runJobs (cli/Jobs.hpp): a failing
// job does not stop the others, up-to-date outputs are skipped (resumable)
// unless --force, a summary table goes to stdout and the exit status is
// non-zero if any job failed.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "Commands.hpp"
#include "Jobs.hpp"
#include "Manifest.hpp"
#include "MeshOptions.hpp"
#include "Threads.hpp"

namespace isohex::cli {

namespace {

namespace fs = std::filesystem;

std::string manifestHelp() {
    return "\nManifest: a .csv file (a header row naming the columns, then one job per row) or a .jsonl/.ndjson file\n"
           "(one JSON object per line with the same keys). Paths are relative to the manifest's folder; output\n"
           "folders are created. An empty "
           "field (or a missing key, or null) takes the value given on the command line. Columns:\n" +
           manifestColumnsHelp() +
           "Example (CSV):\n"
           "  input,output,size,label\n"
           "  ct1.nii.gz,ct1.vtu;ct1.exo,2,\n"
           "  atlas.nii.gz,atlas.vtu,,\"3,7\"\n"
           "Example (JSON lines):\n"
           "  {\"input\": \"ct1.nii.gz\", \"output\": [\"ct1.vtu\", \"ct1.exo\"], \"size\": 2, \"report\": \"ct1.json\"}\n"
           "A job whose outputs (and report and plot) are newer than its input is skipped; editing the\n"
           "manifest does not make outputs stale, so rerun with --force after changing a job's options.";
}

// Output folders are made before the jobs run (as workflow engines do); a
// folder that cannot be made fails only its job, when the job writes there.
void makeOutputFolders(const std::vector<Job>& jobs) {
    for (const Job& job : jobs) {
        std::vector<std::string> all = job.outputs;
        all.push_back(job.report);
        all.push_back(job.plot);
        for (const auto& o : all) {
            const fs::path parent = fs::path(o).parent_path();
            std::error_code ec;
            if (!o.empty() && !parent.empty()) fs::create_directories(parent, ec);
        }
    }
}

struct BatchCommand {
    std::string manifest;
    MeshArgs args;
};

}  // namespace

void addBatchCommand(CLI::App& app) {
    auto c = std::make_shared<BatchCommand>();
    CLI::App* cmd = app.add_subcommand(
        "batch", "Mesh every job of a CSV or JSON-lines manifest; continues past failures, skips up-to-date outputs");
    cmd->add_option("manifest", c->manifest, "Jobs: a .csv file or a .jsonl/.ndjson file (see below)")->required();
    addMeshOptions(cmd, c->args);
    addRunOptions(cmd, c->args.run);
    cmd->footer(manifestHelp());
    cmd->callback([c] {
        const std::vector<Job> jobs = readManifest(c->manifest, c->args);
        applyThreads(c->args.run.threads);
        makeOutputFolders(jobs);
        if (jobs.empty()) {
            ProgressSink sink(c->args.run.progressMode());
            sink.note("warning", c->manifest + ": the manifest lists no jobs");
        }
        pendingExitCode() =
            runJobs(jobs, c->args.run.force, c->args.run.progressMode(), SettingNames::Columns).exitCode();
    });
}

}  // namespace isohex::cli

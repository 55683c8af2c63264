// isohex estimate INPUT [mesh options]: hexes, peak memory, time and threads
// of `isohex mesh` with those options, as JSON, without meshing (what a
// cluster job should ask for; workflow/Snakefile reads it).
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "Commands.hpp"
#include "Isolate.hpp"
#include "MeshOptions.hpp"
#include "Progress.hpp"
#include "Threads.hpp"
#include "isohex/pipeline/Estimate.hpp"

namespace isohex::cli {

namespace {
struct EstimateCommand {
    std::string input;
    pipeline::EstimateOptions options;
    MeshArgs args;
};
}  // namespace

void addEstimateCommand(CLI::App& app) {
    auto c = std::make_shared<EstimateCommand>();
    CLI::App* cmd = app.add_subcommand(
        "estimate",
        "Print the hexes, peak memory and time `isohex mesh` would take with these options, as JSON, without "
        "meshing: on --threads threads, or on the fewest (up to --max-threads) expected to finish within "
        "--target-seconds");
    cmd->add_option("input", c->input, "Scan or label map, as for isohex mesh")->required();
    cmd->add_option("--max-threads", c->options.maxThreads,
                    "Without --threads: the most threads to choose (the fewest that are expected to finish "
                    "within --target-seconds)")
        ->check(CLI::Range(1, 1024))
        ->capture_default_str();
    cmd->add_option("--target-seconds", c->options.targetSeconds,
                    "Without --threads: the wall time the chosen threads aim at")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    addMeshOptions(cmd, c->args);
    addRunOptions(cmd, c->args.run, {RunOption::Threads, RunOption::Quiet, RunOption::LogJson});
    cmd->callback([c] {
        applyThreads(c->args.run.threads);
        checkSettings(c->args);
        c->options.threads = c->args.run.threads;
        const nlohmann::json j = runIsolated(c->input, {}, [&] {
            ProgressSink sink(c->args.run.progressMode());
            pipeline::PreparedFacts facts;
            const pipeline::MeshEstimate e = pipeline::estimateMesh(c->input, c->args.settings, c->options, sink, &facts);
            return pipeline::toJson(e, facts);
        });
        std::cout << j.dump(2) << "\n";
    });
}

}  // namespace isohex::cli

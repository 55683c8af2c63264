// isohex mesh INPUT -o OUTPUT: the whole pipeline; several inputs with --out-dir.
#include <filesystem>
#include <map>
#include <memory>

#include "Commands.hpp"
#include "Jobs.hpp"
#include "MeshOptions.hpp"
#include "Threads.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/MeshIO.hpp"

namespace isohex::cli {

namespace {
struct MeshCommand {
    std::vector<std::string> inputs;
    std::vector<std::string> outputs;
    std::string outDir;
    std::vector<std::string> formats{"vtu"};
    std::string report;
    std::string plot;
    MeshArgs args;
};
}  // namespace

void addMeshCommand(CLI::App& app) {
    auto c = std::make_shared<MeshCommand>();
    CLI::App* cmd = app.add_subcommand("mesh", "Mesh a scan, label map or surface into all-hex elements");
    cmd->add_option("input", c->inputs, "Scan(s): NIfTI, NRRD, MetaImage, TIFF, DICOM folder, OpenVDB, OpenEXR folder")
        ->required();
    cmd->add_option("-o,--output", c->outputs,
                    "Output mesh file(s); the format follows the extension (.vtu .msh .exo .e .inp .mesh)");
    cmd->add_option("--out-dir", c->outDir, "With several inputs: write <input name>.<format> files here");
    cmd->add_option("--format", c->formats, "With --out-dir: output format(s) by extension, e.g. vtu,exo")
        ->delimiter(',');
    cmd->add_option("--report", c->report, "Write the JSON report here (with --out-dir: <name>.report.json always)");
    cmd->add_option("--plot", c->plot, "Write an SVG histogram of the scaled Jacobian here");
    addMeshOptions(cmd, c->args);
    addRunOptions(cmd, c->args.run);
    cmd->callback([c] {
        applyThreads(c->args.run.threads);
        std::vector<Job> jobs;
        if (c->inputs.size() == 1 && c->outDir.empty()) {
            if (c->outputs.empty())
                throw Error("no output given: add -o mesh.vtu (or .msh .exo .e .inp .mesh), several -o for several formats");
            jobs.push_back({c->inputs[0], c->outputs, c->report, c->plot, c->args});
            ProgressSink sink(c->args.run.progressMode());
            const JobResult r = runJobIsolated(jobs[0], sink);
            std::printf("%s: %zu hexes, scaled Jacobian min %.3f mean %.3f, %zu below 0.2, %zu inverted, %.1f s\n",
                        c->inputs[0].c_str(), r.hexes, r.minScaledJacobian, r.meanScaledJacobian, r.below02, r.inverted,
                        r.seconds);
            if (r.written)
                for (const auto& o : c->outputs) std::printf("wrote %s\n", o.c_str());
            if (r.status == "below") {
                std::fflush(stdout);
                sink.note("error", c->inputs[0] + ": " + r.message);
                pendingExitCode() = kExitBelowQuality;
            } else if (!r.message.empty()) {
                sink.note("warning", r.message);  // stderr (a JSON line with --log-json)
            }
            return;
        }
        if (c->outDir.empty()) throw Error("several inputs need --out-dir DIR (outputs are named after the inputs)");
        if (!c->outputs.empty()) throw Error("-o names one output; with several inputs use --out-dir and --format");
        if (!c->report.empty() || !c->plot.empty())
            throw Error("--report/--plot name one file; with --out-dir every job writes <name>.report.json");
        std::error_code ec;
        std::filesystem::create_directories(c->outDir, ec);
        if (ec) throw Error(c->outDir + ": cannot create the output folder: " + ec.message());
        // Outputs are named after the inputs: two inputs with one name would
        // write the same files (the second replacing the first, or skipped as
        // "up to date" without --force).
        std::map<std::string, std::string> byStem;
        for (const auto& in : c->inputs) {
            const auto [it, fresh] = byStem.emplace(stemOf(in), in);
            if (!fresh)
                throw Error(it->second + " and " + in + " would both write " +
                            (std::filesystem::path(c->outDir) / it->first).string() +
                            ".*; mesh them in separate runs (or --out-dir folders), or use `isohex batch` to name "
                            "each output");
        }
        for (const auto& in : c->inputs) {
            Job j{in, {}, {}, {}, c->args};
            const std::string base = (std::filesystem::path(c->outDir) / stemOf(in)).string();
            for (const auto& f : c->formats) j.outputs.push_back(base + "." + (f.front() == '.' ? f.substr(1) : f));
            j.report = base + ".report.json";
            jobs.push_back(std::move(j));
        }
        for (const auto& o : jobs.front().outputs) io::formatFromPath(o);
        pendingExitCode() = runJobs(jobs, c->args.run.force, c->args.run.progressMode(), SettingNames::Flags).exitCode();
    });
}

}  // namespace isohex::cli

// isohex quality MESH: judge a mesh from any tool (quality and validity).
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "Commands.hpp"
#include "Isolate.hpp"
#include "JobStage.hpp"
#include "Jobs.hpp"
#include "RunOptions.hpp"
#include "Threads.hpp"
#include "Report.hpp"
#include "Versions.hpp"
#include "isohex/core/MeshIO.hpp"
#include "isohex/core/Pieces.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/Validate.hpp"

namespace isohex::cli {

namespace {
struct QualityArgs {
    std::string mesh;
    bool json = false;
    bool strict = false;
    std::string reportPath;
    std::string annotated;
    RunArgs run;
};
}  // namespace

void addQualityCommand(CLI::App& app) {
    auto args = std::make_shared<QualityArgs>();
    std::string formats;
    for (const auto& e : io::readableExtensions()) formats += (formats.empty() ? "" : ", ") + e;
    CLI::App* cmd =
        app.add_subcommand("quality", "Report element quality and validity of a hex mesh (" + formats + ")");
    cmd->add_option("mesh", args->mesh, "Mesh file to judge")->required();
    cmd->add_flag("--json", args->json, "Print the report as JSON on stdout instead of text");
    cmd->add_option("--report", args->reportPath, "Also write the JSON report to this file");
    cmd->add_option("-o,--annotate", args->annotated,
                    "Write the mesh again with per-hex quality fields (scaled_jacobian, inverse_mean_ratio, "
                    "condition, edge_ratio, volume), e.g. to look at it in ParaView");
    cmd->add_flag("--strict", args->strict,
                  "Exit with status 3 if the mesh has a validity defect or an inverted or degenerate hex");
    addRunOptions(cmd, args->run, {RunOption::Threads, RunOption::Force});
    cmd->callback([args] {
        applyThreads(args->run.threads);
        std::vector<std::string> outputs;
        if (!args->reportPath.empty()) outputs.push_back(args->reportPath);
        if (!args->annotated.empty()) {
            io::formatFromPath(args->annotated);
            outputs.push_back(args->annotated);
        }
        checkOutputPaths(outputs, {args->mesh}, args->run.force);
        // In a child process, as isohex mesh: a reader crashing on a damaged
        // file is an error naming it (cli/Isolate.hpp).
        const nlohmann::json done = runIsolated(args->mesh, outputs, [&] {
            nowReading(args->mesh);
            const HexMesh mesh = io::read(args->mesh);
            stageBegins("quality");
            const HexQuality q = computeQuality(mesh);
            const QualitySummary s = summarize(mesh, q);
            const ValidityReport v = validate(mesh);
            nlohmann::json j = toJson(s);
            j["mesh"] = args->mesh;
            j["validity"] = toJson(v);
            const std::vector<MeshPiece> pieces = meshPieces(mesh);
            j["pieces"] = toJson(pieces);
            j["peak_memory_mb"] = peakMemoryMb();
            j["versions"] = versionsJson();
            if (!args->reportPath.empty()) writeJsonFile(j, args->reportPath, args->run.force);
            if (!args->annotated.empty()) {
                io::WriteOptions w;
                w.overwrite = args->run.force;
                w.scaledJacobian = q.scaledJacobian;
                w.cellFields = {{"inverse_mean_ratio", q.inverseMeanRatio},
                                {"condition", q.condition},
                                {"edge_ratio", q.edgeRatio},
                                {"volume", q.volume}};
                io::write(mesh, args->annotated, w);
                if (io::formatFromPath(args->annotated) != io::Format::Vtu)
                    std::cerr << "isohex: note: " << args->annotated
                              << ": the per-hex quality fields are written to .vtu files only; this file holds the mesh\n";
            }
            if (args->json) std::cout << j.dump(2) << "\n";
            else {
                std::cout << args->mesh << "\n" << formatQuality(s, v);
                if (const std::string d = describePieces(pieces); !d.empty()) std::cout << d << "\n";
            }
            std::cout.flush();
            return nlohmann::json{{"invalid", args->strict && (!v.ok() || s.inverted > 0 || s.degenerate > 0)}};
        });
        if (done.value("invalid", false)) pendingExitCode() = kExitInvalidMesh;
    });
}

}  // namespace isohex::cli

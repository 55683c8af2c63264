// isohex smooth MESH -o OUT: untangle and optimise a hex mesh from any tool,
// boundary nodes fixed (there is no isosurface to keep them on).
#include <cstdio>
#include <memory>

#include "Commands.hpp"
#include "Isolate.hpp"
#include "JobStage.hpp"
#include "Jobs.hpp"
#include "Progress.hpp"
#include "RunOptions.hpp"
#include "Threads.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/MeshIO.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/pipeline/OptimizerProgress.hpp"
#include "isohex/smoothing/Optimize.hpp"
#include "isohex/smoothing/WorstHexes.hpp"

namespace isohex::cli {

namespace {
struct SmoothArgs {
    std::string input, output;
    RunArgs run;
};
}  // namespace

void addSmoothCommand(CLI::App& app) {
    auto a = std::make_shared<SmoothArgs>();
    CLI::App* cmd = app.add_subcommand(
        "smooth", "Untangle and optimise the interior nodes of a hex mesh (.vtu, .msh); boundary nodes stay fixed");
    cmd->add_option("mesh", a->input, "Mesh to improve")->required();
    cmd->add_option("-o,--output", a->output, "Where to write the improved mesh")->required();
    addRunOptions(cmd, a->run, {RunOption::Force, RunOption::Quiet, RunOption::Threads});
    cmd->callback([a] {
        applyThreads(a->run.threads);
        io::formatFromPath(a->output);
        checkOutputPaths({a->output}, {a->input}, a->run.force);
        // In a child process, as isohex mesh (cli/Isolate.hpp).
        runIsolated(a->input, {a->output}, [&] {
            nowReading(a->input);
            HexMesh mesh = io::read(a->input);
            stageBegins("check");
            classifyBoundaryNodes(mesh);
            const HexQuality qBefore = computeQuality(mesh);
            const QualitySummary before = summarize(mesh, qBefore);
            refuseMirroredCornerOrder(a->input, before.inverted, mesh.hexCount(), "smoothing would only scramble the mesh");
            const std::vector<Vec3> original = mesh.nodes;
            smoothing::SmoothingOptions opt;
            opt.fixBoundary = true;
            ProgressSink sink(a->run.progressMode(), {}, {"optimize"});
            sink.begin("optimize");
            const Stopwatch optimizing;
            PhasedProgress phased = pipeline::optimizerProgress(sink, pipeline::WorstHexesInStage::Yes);
            const auto r = smoothing::optimizeMesh(mesh, nullptr, opt, phased.callback());
            // The mean-ratio sweeps raise the average and can lower the worst hex
            // (on an already optimised label-map mesh, by a factor of three): the
            // max-min pass after them, as isohex mesh runs it, with the boundary fixed.
            smoothing::raiseWorstHexes(mesh, nullptr, smoothing::WorstHexOptions{}, nullptr, phased.callback());
            sink.end("optimize", optimizing.seconds());
            HexQuality q = computeQuality(mesh);
            QualitySummary after = summarize(mesh, q);
            // Never hand back a worse mesh: fewer inverted hexes, or as many and a
            // minimum no lower, or the input's positions stay.
            const bool worse = after.inverted > before.inverted ||
                               (after.inverted == before.inverted && after.scaledJacobian.min < before.scaledJacobian.min);
            if (worse) {
                sink.note("warning", "smoothing lowered the worst hex (scaled Jacobian min " +
                                         std::to_string(before.scaledJacobian.min) + " -> " +
                                         std::to_string(after.scaledJacobian.min) + ", inverted " +
                                         std::to_string(before.inverted) + " -> " + std::to_string(after.inverted) +
                                         "); the input's node positions are written unchanged");
                mesh.nodes = original;
                q = qBefore;
                after = before;
            }
            if (after.inverted > 0) {
                sink.note("warning", std::to_string(after.inverted) + " of " + std::to_string(mesh.hexCount()) +
                                         " hexes stay inverted; the boundary nodes are fixed, so hexes folded at the "
                                         "boundary need the mesh remade");
            }
            io::WriteOptions w2;
            w2.overwrite = a->run.force;
            w2.scaledJacobian = q.scaledJacobian;
            io::write(mesh, a->output, w2);
            std::printf("%s: %zu hexes; scaled Jacobian min %.3f -> %.3f, mean %.3f -> %.3f; inverted %zu -> %zu; %d sweeps\n",
                        a->input.c_str(), mesh.hexCount(), before.scaledJacobian.min, after.scaledJacobian.min,
                        before.scaledJacobian.mean, after.scaledJacobian.mean, before.inverted, after.inverted, r.sweeps);
            std::printf("wrote %s\n", a->output.c_str());
            std::fflush(stdout);
            return nlohmann::json::object();
        });
    });
}

}  // namespace isohex::cli

// isohex smooth MESH -o OUT: untangle and optimise a hex mesh from any tool,
// boundary nodes fixed (there is no isosurface to keep them on).
#include <cstdio>
#include <memory>

#include "Commands.hpp"
#include "Jobs.hpp"
#include "Progress.hpp"
#include "isohex/core/MeshIO.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/Optimize.hpp"

namespace isohex::cli {

namespace {
struct SmoothArgs {
    std::string input, output;
    bool force = false, quiet = false;
    int threads = 0;
};
}  // namespace

void addSmoothCommand(CLI::App& app) {
    auto a = std::make_shared<SmoothArgs>();
    CLI::App* cmd = app.add_subcommand(
        "smooth", "Untangle and optimise the interior nodes of a hex mesh (.vtu, .msh); boundary nodes stay fixed");
    cmd->add_option("mesh", a->input, "Mesh to improve")->required();
    cmd->add_option("-o,--output", a->output, "Where to write the improved mesh")->required();
    cmd->add_flag("--force", a->force, "Overwrite an existing output");
    cmd->add_flag("-q,--quiet", a->quiet, "No progress output");
    cmd->add_option("--threads", a->threads, "Worker threads (results do not depend on it)")->check(CLI::Range(1, 1024));
    cmd->callback([a] {
        applyThreads(a->threads);
        io::formatFromPath(a->output);
        checkOutputPaths({a->output}, {a->input}, a->force);
        HexMesh mesh = io::read(a->input);
        classifyBoundaryNodes(mesh);
        const QualitySummary before = summarize(mesh, computeQuality(mesh));
        smoothing::SmoothingOptions opt;
        opt.fixBoundary = true;
        ProgressSink sink(a->quiet ? ProgressSink::Mode::Quiet : ProgressSink::Mode::Auto);
        sink.begin("optimize");
        const auto r = smoothing::optimizeMesh(mesh, nullptr, opt, [&](std::string_view, double f) { sink.progress(f); });
        sink.end("optimize", r.seconds);
        const HexQuality q = computeQuality(mesh);
        const QualitySummary after = summarize(mesh, q);
        io::WriteOptions w;
        w.overwrite = a->force;
        w.scaledJacobian = q.scaledJacobian;
        io::write(mesh, a->output, w);
        std::printf("%s: %zu hexes; scaled Jacobian min %.3f -> %.3f, mean %.3f -> %.3f; inverted %zu -> %zu; %d sweeps\n",
                    a->input.c_str(), mesh.hexCount(), before.scaledJacobian.min, after.scaledJacobian.min,
                    before.scaledJacobian.mean, after.scaledJacobian.mean, before.inverted, after.inverted, r.sweeps);
        std::printf("wrote %s\n", a->output.c_str());
    });
}

}  // namespace isohex::cli

// isohex insert-sheet --mesh IN --surface S.stl [--surface T.stl ...] -o OUT:
// the seed's sheet insertion along triangle surfaces into an existing hex mesh
// (section 5.4), several surfaces in turn (chapter 6), then smoothing with
// surface nodes on their triangles and curve nodes on their curves.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>

#include "Commands.hpp"
#include "Isolate.hpp"
#include "JobStage.hpp"
#include "Jobs.hpp"
#include "MeshOptions.hpp"
#include "Progress.hpp"
#include "RunOptions.hpp"
#include "Threads.hpp"
#include "Report.hpp"
#include "isohex/pipeline/MinQuality.hpp"
#include "isohex/pipeline/OptimizerProgress.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "isohex/pipeline/SheetMethod.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/MeshIO.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/insertion/SheetInsertion.hpp"
#include "isohex/smoothing/Optimize.hpp"

namespace isohex::cli {

namespace {
struct InsertSheetArgs {
    std::string mesh, output;
    std::vector<std::string> surfaces;
    insertion::Keep keep = insertion::Keep::Both;
    insertion::Intersected intersected = insertion::Intersected::Auto;
    bool optimize = true;
    RunArgs run;
    MeshArgs quality;  // --min-quality and --allow-below (the option table's rows)
};

// The mesh the surfaces cut may be any mesh, made with any means, so the
// default minimum is no inverted or degenerate hex.
double minQualityOf(const InsertSheetArgs& a) {
    return a.quality.settings.minQuality.value_or(pipeline::kDefaultMinQualityAnyMesh);
}

// After the optimiser, a max-min pass aimed at the minimum quality where
// hexes are below it (none otherwise: the mesh stays as optimised); then the
// certificate. Prints the places when it is not met.
pipeline::QualityCertificate meetMinQuality(HexMesh& mesh, const insertion::SheetGeometry& geometry,
                                            const InsertSheetArgs& a) {
    const double target = minQualityOf(a);
    pipeline::QualityCertificate c = pipeline::certifyQuality(mesh, target, nullptr, a.optimize);
    if (!c.certified && a.optimize) {
        pipeline::worstHexPass(mesh, &geometry, std::max(target, smoothing::WorstHexOptions{}.target));
        c = pipeline::certifyQuality(mesh, target);
        c.worstHexTarget = std::max(target, smoothing::WorstHexOptions{}.target);
    }
    c.defaultTarget = !a.quality.settings.minQuality.has_value();
    return c;
}
}  // namespace

void addInsertSheetCommand(CLI::App& app) {
    auto a = std::make_shared<InsertSheetArgs>();
    CLI::App* cmd = app.add_subcommand(
        "insert-sheet", "Insert two hex sheets along closed triangle surfaces into a hex mesh (seed 5.4, chapter 6)");
    cmd->add_option("--mesh", a->mesh, "Hex mesh to cut (.vtu .msh)")->required();
    cmd->add_option("--surface", a->surfaces,
                    "Closed triangle surface (.stl .obj .ply .off); repeat to insert several in turn")
        ->required();
    cmd->add_option("-o,--output", a->output, "Where to write the result; the format follows the extension")->required();
    const std::map<std::string, insertion::Keep> keeps{
        {"inside", insertion::Keep::Inside}, {"outside", insertion::Keep::Outside}, {"both", insertion::Keep::Both}};
    cmd->add_option_function<std::string>(
           "--keep", [a, keeps](const std::string& v) { a->keep = keeps.at(v); },
           "Which side of each surface to keep: inside, outside or both (default)")
        ->check(CLI::IsMember({"inside", "outside", "both"}));
    const std::map<std::string, insertion::Intersected> sides{{"auto", insertion::Intersected::Auto},
                                                              {"side1", insertion::Intersected::Side1},
                                                              {"side2", insertion::Intersected::Side2}};
    cmd->add_option_function<std::string>(
           "--intersected", [a, sides](const std::string& v) { a->intersected = sides.at(v); },
           "Hexes cut by the surface join: auto (the side of their centroid, default), side1 (inside) "
           "or side2 (outside)")
        ->check(CLI::IsMember({"auto", "side1", "side2"}));
    cmd->add_flag("!--no-optimize", a->optimize, "Skip untangling and optimisation");
    addRunOptions(cmd, a->run, {RunOption::Force, RunOption::Quiet, RunOption::Threads});
    addMeshOptions(cmd, a->quality, {"min-quality", "allow-below"});
    cmd->callback([a] {
        applyThreads(a->run.threads);
        const Stopwatch total;
        io::formatFromPath(a->output);
        {
            std::vector<std::string> inputs = a->surfaces;
            inputs.push_back(a->mesh);
            checkOutputPaths({a->output}, inputs, a->run.force);
        }
        if (!std::filesystem::exists(a->mesh)) throw Error(a->mesh + ": no such file; check the path");
        // In a child process, as isohex mesh: a reader crashing on a damaged
        // file is an error naming it (cli/Isolate.hpp).
        const nlohmann::json done = runIsolated(a->mesh, {a->output}, [&] {
            // Every surface is read and checked before any work.
            std::vector<std::shared_ptr<const insertion::TriangleTree>> trees;
            for (const auto& s : a->surfaces) {
                nowReading(s);
                trees.push_back(pipeline::loadTriangleTree(s));
            }
            nowReading(a->mesh);
            HexMesh mesh = io::read(a->mesh);
            stageBegins("check");
            {
                const std::vector<double> sj = scaledJacobians(mesh);
                const auto inverted = static_cast<std::size_t>(std::count_if(sj.begin(), sj.end(), [](double v) { return v < 0; }));
                refuseMirroredCornerOrder(a->mesh, inverted, mesh.hexCount(),
                                          "the sheets would be inserted between inverted hexes and the result scrambled");
            }
            stageBegins("insert");
            insertion::SheetGeometry geometry;
            insertion::adoptBoundary(mesh, geometry);
            insertion::InsertOptions o;
            o.keep = a->keep;
            o.intersected = a->intersected;
            for (const auto& t : trees) {
                const insertion::InsertResult r = insertion::insertSheets(mesh, geometry, t, o);
                std::printf("%s: %zu hexes cut, %zu moved for manifold sides (%zu edges, %zu nodes), %zu sheet hexes, "
                            "%zu surface and %zu curve nodes, %.2f s\n",
                            t->name().c_str(), r.intersectedHexes, r.hexesMoved, r.nonManifoldEdgesFixed,
                            r.nonManifoldNodesFixed, r.sheetHexes, r.surfaceNodes, r.curveNodes, r.seconds);
            }
            std::size_t invertedBefore = 0, invertedAfter = 0;
            if (a->optimize) {
                ProgressSink sink(a->run.progressMode(), {}, {"optimize"});
                sink.begin("optimize");
                PhasedProgress phased = pipeline::optimizerProgress(sink, pipeline::WorstHexesInStage::No);
                const auto r = smoothing::optimizeMesh(mesh, &geometry, {}, phased.callback());
                sink.end("optimize", r.seconds);
                invertedBefore = r.invertedBefore;
                invertedAfter = r.invertedAfter;
            }
            const pipeline::QualityCertificate cert = meetMinQuality(mesh, geometry, *a);
            if (!cert.certified) {
                std::fflush(stdout);
                std::cerr << "isohex: error: " << a->output << ": below the minimum quality " << cert.target
                          << ": smallest scaled Jacobian " << cert.achieved << ", " << cert.hexesBelow
                          << " hex(es) below it"
                          << (a->quality.settings.allowBelow ? " (written: --allow-below)"
                                                             : " (nothing written; --allow-below writes it)")
                          << ":\n"
                          << pipeline::describePlaces(cert, 10);
                // (this runs in the child: the parent sets the exit status)
                if (!a->quality.settings.allowBelow) return nlohmann::json{{"below_quality", true}};
            }
            const HexQuality q = computeQuality(mesh);
            const QualitySummary s = summarize(mesh, q);
            const ValidityReport v = validate(mesh);
            io::WriteOptions w;
            w.overwrite = a->run.force;
            w.scaledJacobian = q.scaledJacobian;
            io::write(mesh, a->output, w);
            // Without the optimiser the hexes are as inserted: there is no
            // "before smoothing" to compare with.
            const std::string inverted =
                a->optimize ? std::to_string(s.inverted) + " inverted (" + std::to_string(invertedBefore) + " before smoothing)"
                            : std::to_string(s.inverted) + " inverted (not smoothed: --no-optimize)";
            std::printf("%s: %zu hexes, scaled Jacobian min %.3f mean %.3f, %s, %s, %.1f s\n", a->output.c_str(), s.hexes,
                        s.scaledJacobian.min, s.scaledJacobian.mean, inverted.c_str(), v.ok() ? "valid" : "validity defects",
                        total.seconds());
            (void)invertedAfter;
            std::printf("wrote %s\n", a->output.c_str());
            if (!v.ok())
                std::cerr << "isohex: warning: " << a->output << ": " << describeDefects(v)
                          << (a->optimize ? "" : "; run without --no-optimize to untangle them")
                          << "; isohex quality " << a->output << " lists them\n";
            std::fflush(stdout);
            return nlohmann::json{{"below_quality", !cert.certified}};
        });
        if (done.value("below_quality", false)) pendingExitCode() = kExitBelowQuality;
    });
}

}  // namespace isohex::cli

// isohex merge PARTS... -o OUT: the parts of a split scan (mesh --part K/N)
// joined into one conformal mesh (pipeline/Merge.hpp).
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include "Commands.hpp"
#include "Isolate.hpp"
#include "JobStage.hpp"
#include "Jobs.hpp"
#include "MeshOptions.hpp"
#include "Progress.hpp"
#include "Report.hpp"
#include "RunOptions.hpp"
#include "Threads.hpp"
#include "Versions.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/MeshIO.hpp"
#include "isohex/core/Pieces.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/pipeline/Fidelity.hpp"
#include "isohex/pipeline/Merge.hpp"
#include "isohex/pipeline/MinQuality.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/ReportJson.hpp"

namespace isohex::cli {

namespace {
struct MergeArgs {
    std::vector<std::string> parts;
    std::vector<std::string> outputs;
    std::string report;
    bool noBandPass = false;
    bool allowBelow = false;
    std::string scan;  // the scan the parts were meshed from, with the parts' options in `mesh`
    MeshArgs mesh;
    RunArgs run;
};

// The mesh options merge takes with --scan: every one but those merge has
// itself (--allow-below) or that name a part (--part).
std::vector<std::string> scanOptionNames() {
    std::vector<std::string> names;
    for (const MeshOption& o : meshOptions())
        if (o.name != "allow-below" && o.name != "part") names.push_back(o.name);
    return names;
}

// Joins the parts; with --scan (loaded into `p`), the band pass projects onto the scan's isosurface.
pipeline::MergeResult merge(const MergeArgs& a, std::optional<pipeline::Prepared>& p) {
    if (a.scan.empty()) return pipeline::mergeParts(a.parts, !a.noBandPass);
    nowReading(a.scan);
    ProgressSink sink(ProgressSink::Mode::Quiet);
    p = pipeline::prepareGrid(a.scan, a.mesh.settings, sink);
    nowReading(a.parts.front());
    pipeline::MergeScan scan;
    scan.prepared = &*p;
    scan.surfaceToleranceVoxels = a.mesh.settings.surfaceTolerance.value_or(pipeline::kDefaultSurfaceTolerance);
    scan.stretchTarget = pipeline::stretchTargetFor(a.scan, a.mesh.settings);
    return pipeline::mergeParts(a.parts, !a.noBandPass, scan);
}

// Joins, measures and writes; the report as JSON.
nlohmann::json mergeAndWrite(const MergeArgs& a) {
    nowReading(a.parts.front());
    std::optional<pipeline::Prepared> scan;
    pipeline::MergeResult m = merge(a, scan);
    const HexQuality q = computeQuality(m.mesh);
    const QualitySummary s = summarize(m.mesh, q);
    const ValidityReport v = validate(m.mesh);
    nlohmann::json report = {{"merge", pipeline::toJson(m)}};
    // With the scan: the merged mesh against its isosurface, as mesh's report measures a whole run.
    std::optional<pipeline::FidelityResult> fid;
    if (scan) {
        fid = pipeline::fidelity(m.mesh, *scan);
        report["fidelity"] = pipeline::toJson(*fid);
    }
    const nlohmann::json quality = toJson(s);  // (items() of a temporary would dangle)
    for (const auto& [k, val] : quality.items()) report[k] = val;
    report["validity"] = toJson(v);
    report["pieces"] = toJson(meshPieces(m.mesh));
    report["outputs"] = a.outputs;
    report["scan"] = a.scan.empty() ? nlohmann::json(nullptr) : nlohmann::json(a.scan);
    // No mesh with inverted hexes or defects is written without a word (as
    // `mesh` does below its minimum quality): refused unless --allow-below.
    if ((s.inverted > 0 || !v.ok()) && !a.allowBelow)
        throw Error(a.parts.front() + " (and the other parts): the merged mesh has " + std::to_string(s.inverted) +
                    " inverted hexes" + (v.ok() ? std::string() : " and " + describeDefects(v)) +
                    ", at the cuts; nothing was written. Mesh the scan whole or in fewer parts, or give --allow-below "
                    "to write it anyway");
    io::WriteOptions w;
    w.overwrite = a.run.force;
    w.scaledJacobian = q.scaledJacobian;
    stageBegins("write");
    for (const auto& o : a.outputs) io::write(m.mesh, o, w);
    report["peak_memory_mb"] = peakMemoryMb();
    report["versions"] = versionsJson();
    if (!a.report.empty()) writeJsonFile(report, a.report, a.run.force);
    std::printf("merged %d parts: %zu hexes, %zu nodes, scaled Jacobian min %.3f mean %.3f, %zu inverted",
                m.parts, m.mesh.hexCount(), m.mesh.nodeCount(), s.scaledJacobian.min, s.scaledJacobian.mean,
                s.inverted);
    for (const auto& c : m.cuts) std::printf("; cut %d|%d: %zu nodes matched", c.below, c.below + 1, c.nodes);
    if (fid)
        std::printf("; boundary distance mean %.3g p95 %.3g max %.3g, volume %.6g (isosurface %.6g)",
                    fid->boundary.mean, fid->boundary.p95, fid->boundary.max, fid->volumeMesh, fid->volumeIsosurface);
    std::printf("\n");
    for (const auto& o : a.outputs) std::printf("wrote %s\n", o.c_str());
    if (!v.ok()) std::fprintf(stderr, "warning: the merged mesh: %s\n", describeDefects(v).c_str());
    std::fflush(stdout);
    return nlohmann::json::object();
}
}  // namespace

void addMergeCommand(CLI::App& app) {
    auto a = std::make_shared<MergeArgs>();
    CLI::App* cmd = app.add_subcommand(
        "merge", "Join the parts of a split scan (isohex mesh --part K/N, .vtu) into one conformal mesh");
    cmd->add_option("parts", a->parts, "The part files, every part of one split once, in any order")->required();
    cmd->add_option("-o,--output", a->outputs,
                    "Merged mesh file(s); the format follows the extension (.vtu .msh .exo .e .inp .mesh)")
        ->required();
    cmd->add_option("--report", a->report, "Write the JSON report (cuts, matched nodes, quality, validity) here");
    cmd->add_flag("--allow-below", a->allowBelow,
                  "Write the merged mesh even when it has inverted hexes or defects (a warning says so)");
    cmd->add_flag("--no-band-pass", a->noBandPass,
                  "Do not optimise the nodes around the cuts again (each part froze its cut nodes)");
    cmd->add_option("--scan", a->scan,
                    "The scan the parts were meshed from, with the parts' mesh options: the band pass then keeps "
                    "boundary nodes on its isosurface (without, on the merged mesh's boundary)");
    const std::vector<std::string> scanOptions = scanOptionNames();
    addMeshOptions(cmd, a->mesh, scanOptions);
    addRunOptions(cmd, a->run, {RunOption::Threads, RunOption::Force});
    cmd->callback([a, cmd, scanOptions] {
        applyThreads(a->run.threads);
        for (const auto& name : scanOptions)
            if (a->scan.empty() && cmd->count("--" + name) > 0)
                throw CLI::ValidationError("--" + name, "a mesh option needs --scan (the scan the parts were meshed from)");
        if (!a->scan.empty()) checkSettings(a->mesh);
        for (const auto& o : a->outputs) io::formatFromPath(o);
        std::vector<std::string> files = a->outputs;
        if (!a->report.empty()) files.push_back(a->report);
        std::vector<std::string> inputs = a->parts;
        if (!a->scan.empty()) inputs.push_back(a->scan);
        checkOutputPaths(files, inputs, a->run.force);
        runIsolated(a->parts.front(), files, [&] { return mergeAndWrite(*a); });
    });
}

}  // namespace isohex::cli

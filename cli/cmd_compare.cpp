// isohex compare INPUT: the seed's experiment (section 5.3.1) in one command.
// The same input and optimiser, four ways:
//   a  no sheet
//   b  the fundamental sheet pillowed in
//   c  no sheet, random sheets diced in until the element count matches b
//   d  the fundamental sheet, random other sheets extracted until the count matches a
#include <charconv>
#include <filesystem>
#include <cstdio>
#include <memory>

#include <nlohmann/json.hpp>

#include "Commands.hpp"
#include "Isolate.hpp"
#include "Jobs.hpp"
#include "MeshOptions.hpp"
#include "Report.hpp"
#include "Svg.hpp"
#include "Threads.hpp"
#include "Versions.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/MeshIO.hpp"
#include "isohex/core/Collapse.hpp"
#include "isohex/core/Dice.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/SheetSelection.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/pipeline/Contour.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "isohex/pipeline/Pillow.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/ReportJson.hpp"

namespace isohex::cli {

namespace {

struct CompareArgs {
    std::string input;
    std::string json;
    std::string plot;
    std::string meshDir;
    std::uint64_t seed = 1;
    bool moveBoundary = false;
    MeshArgs args;
};

struct Variant {
    std::string key, label;
    HexMesh mesh;
    nlohmann::json ops;
    double seconds = 0;
};

// Dices randomly drawn sheets once each until the mesh has at least `target` hexes.
nlohmann::json diceUntil(HexMesh& mesh, std::size_t target, std::uint64_t seed) {
    nlohmann::json j;
    std::size_t diced = 0;
    for (std::uint64_t round = 0; mesh.hexCount() < target && round < 100000; ++round) {
        const Topology t = buildTopology(mesh);
        const DualSheets s = buildSheets(mesh, t);
        const auto pick = randomSheets(s, 1, seed + round);
        if (pick.empty()) break;
        try {
            dice(mesh, t, s, pick[0], 1);
            ++diced;
        } catch (const Error&) {
            // a self-intersecting sheet: draw another
        }
    }
    j["sheets_diced"] = diced;
    return j;
}

// Extracts randomly drawn non-fundamental sheets until at most `target` hexes
// remain; sheets whose extraction is refused are skipped.
nlohmann::json extractUntil(HexMesh& mesh, std::size_t target, std::uint64_t seed) {
    nlohmann::json j;
    std::size_t extracted = 0, refused = 0;
    for (std::uint64_t round = 0; mesh.hexCount() > target && round < 100000; ++round) {
        const Topology t = buildTopology(mesh);
        const DualSheets s = buildSheets(mesh, t);
        const auto fundamental = fundamentalSheets(mesh, t, s);
        const auto pick = randomSheets(s, 1, seed + round, fundamental);
        if (pick.empty()) break;
        try {
            collapse(mesh, t, s, pick[0]);
            ++extracted;
        } catch (const Error&) {
            ++refused;
            if (refused > 50 + 10 * extracted) break;  // nothing left that can go
        }
    }
    j["sheets_extracted"] = extracted;
    j["extractions_refused"] = refused;
    return j;
}


// --seed: a whole number from 0 to 2^64 - 1 (CLI11 would wrap -1 and cut 1.5).
CLI::Validator seedValidator() {
    return CLI::Validator(
        [](const std::string& v) {
            std::uint64_t n = 0;
            const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), n);
            return !v.empty() && ec == std::errc() && end == v.data() + v.size()
                       ? std::string()
                       : "--seed takes a whole number from 0 to 18446744073709551615 (got '" + v + "')";
        },
        "", "whole number");
}

// The settings every variant is meshed with: the mesh options checked, and
// the boundary fixed unless --move-boundary. Refuses the options that would
// make the variants differ in more than their sheets.
pipeline::MeshSettings compareSettings(const CompareArgs& c) {
    MeshArgs args = c.args;
    checkSettings(args);
    pipeline::MeshSettings s = args.settings;
    if (s.surfaceTolerance && !c.moveBoundary)
        throw Error("--surface-tolerance needs --move-boundary: without it compare keeps surface nodes fixed "
                    "(the seed's protocol)");
    if (s.retries.value_or(0) > 0 || s.retryBelow.value_or(0) > 0)
        throw Error(std::string(s.retries.value_or(0) > 0 ? "--retries" : "--retry-below") +
                    " is for isohex mesh: compare meshes every variant from one grid, and editing the grid for "
                    "one variant would make them differ");
    if (s.minQuality || s.allowBelow || s.maxDeviation)
        throw Error("--min-quality, --allow-below and --max-deviation are for the meshes isohex mesh writes: compare "
                    "reports the variants' quality as they come (leave them out)");
    s.fixBoundary = !c.moveBoundary;
    s.fixBoundaryByCompare = s.fixBoundary;
    return s;
}

std::string variantMeshPath(const CompareArgs& c, const std::string& key) {
    return (std::filesystem::path(c.meshDir) / ("variant_" + key + ".vtu")).string();
}

// Every output, checked before the four meshings (the variant meshes too);
// the folder of the variant meshes is made.
std::vector<std::string> compareOutputs(const CompareArgs& c) {
    std::vector<std::string> outputs;
    if (!c.json.empty()) outputs.push_back(c.json);
    if (!c.plot.empty()) outputs.push_back(c.plot);
    if (!c.meshDir.empty()) {
        std::error_code ec;
        std::filesystem::create_directories(c.meshDir, ec);
        if (ec) throw Error(c.meshDir + ": cannot create the folder for the variant meshes: " + ec.message());
        for (const char* k : {"a", "b", "c", "d"}) outputs.push_back(variantMeshPath(c, k));
    }
    checkOutputPaths(outputs, {c.input}, c.args.run.force);
    return outputs;
}

// The four variants before optimisation, from one extraction: a as
// extracted, b pillowed, c diced up to b's count, d (from b) extracted down
// to a's. Each variant's seconds are the time of its sheet operations.
std::vector<Variant> makeVariants(const pipeline::Prepared& p, const pipeline::MeshSettings& s, std::uint64_t seed, ProgressSink& sink) {
    const HexMesh base = pipeline::contour(p, s, sink);
    std::vector<Variant> variants(4);
    variants[0] = {"a", "no sheet", base, {}, 0};
    variants[1] = {"b", "fundamental sheet", base, {}, 0};
    pipeline::MeshSettings pillowed = s;
    pillowed.pillow = true;
    {
        const Stopwatch t;
        variants[1].ops = pipeline::toJson(pipeline::pillowBoundary(variants[1].mesh, pillowed, sink));
        variants[1].seconds += t.seconds();
    }
    variants[2] = {"c", "no sheet, random sheets diced in", base, {}, 0};
    {
        sink.begin("dice");
        const Stopwatch t;
        variants[2].ops = diceUntil(variants[2].mesh, variants[1].mesh.hexCount(), seed);
        variants[2].seconds += t.seconds();
        sink.end("dice", variants[2].seconds);
    }
    variants[3] = {"d", "fundamental sheet, random sheets extracted", variants[1].mesh, {}, 0};
    {
        sink.begin("extract sheets");
        const Stopwatch t;
        variants[3].ops = extractUntil(variants[3].mesh, base.hexCount(), seed);
        variants[3].seconds += t.seconds() + variants[1].seconds;
        sink.end("extract sheets", t.seconds());
    }
    return variants;
}

// Optimises each variant, prints its line of the table, writes its mesh
// (with --mesh-dir) and returns the comparison's JSON; `series` gets each
// variant's histogram.
nlohmann::json optimizeVariants(std::vector<Variant>& variants, const pipeline::Prepared& p, const pipeline::MeshSettings& s,
                                const CompareArgs& c, ProgressSink& sink, std::vector<HistogramSeries>& series) {
    nlohmann::json out;
    out["input"] = pipeline::toJson(p.facts.input);
    out["grid"] = pipeline::toJson(p.facts.grid);
    out["protocol"] = s.fixBoundary ? "boundary quads smoothed on the isosurface, then boundary nodes fixed, interior "
                                      "optimised (seed 5.2.2)"
                                    : "boundary nodes slide on the isosurface";
    out["seed"] = c.seed;
    std::printf("%-44s %9s %8s %8s %8s %9s %8s\n", "variant", "hexes", "min SJ", "mean SJ", "<0.2", "inverted",
                "seconds");
    for (auto& v : variants) {
        const Stopwatch t;
        sink.setJob("variant " + v.key);  // its warnings say which variant they are about
        // the seed's protocol: the boundary quads improved on the isosurface
        // before the boundary is fixed
        nlohmann::json quads;
        if (s.fixBoundary) quads = pipeline::toJson(pipeline::smoothBoundaryOnIsosurface(v.mesh, p, sink));
        const nlohmann::json opt = pipeline::toJson(pipeline::optimize(v.mesh, p, s, sink));
        sink.setJob({});
        v.seconds += t.seconds();
        const HexQuality q = computeQuality(v.mesh);
        const QualitySummary qs = summarize(v.mesh, q);
        nlohmann::json j = toJson(qs);
        j["variant"] = v.key;
        j["label"] = v.label;
        j["operations"] = v.ops;
        j["optimization"] = opt;
        if (!quads.is_null()) j["boundary_quads"] = quads;
        j["seconds"] = v.seconds;
        out["variants"].push_back(j);
        series.push_back({v.key + ": " + v.label, qs.histogram, qs.degenerate});
        std::printf("%-44s %9zu %8.3f %8.3f %8zu %9zu %8.1f\n", (v.key + ") " + v.label).c_str(), qs.hexes,
                    qs.scaledJacobian.min, qs.scaledJacobian.mean, qs.below02, qs.inverted, v.seconds);
        if (!c.meshDir.empty()) {
            std::filesystem::create_directories(c.meshDir);
            io::WriteOptions w;
            w.overwrite = c.args.run.force;
            w.scaledJacobian = q.scaledJacobian;
            io::write(v.mesh, variantMeshPath(c, v.key), w);
        }
    }
    return out;
}

}  // namespace

void addCompareCommand(CLI::App& app) {
    auto c = std::make_shared<CompareArgs>();
    CLI::App* cmd = app.add_subcommand(
        "compare", "The seed's experiment: quality without a boundary sheet, with it, and with random sheets "
                   "diced in or extracted to match element counts");
    cmd->add_option("input", c->input, "Scan to mesh")->required();
    cmd->add_option("--json", c->json, "Write the comparison as JSON here");
    cmd->add_option("--plot", c->plot, "Write an SVG histogram of the scaled Jacobian per variant here");
    cmd->add_option("--mesh-dir", c->meshDir, "Also write each variant's mesh (variant_a.vtu ...) into this folder");
    cmd->add_option("--seed", c->seed, "Seed for the random sheet choices (default 1)")->check(seedValidator());
    cmd->add_flag("--move-boundary", c->moveBoundary,
                  "Let surface nodes slide on the isosurface (default: fixed, the seed's protocol)");
    addMeshOptions(cmd, c->args);
    addRunOptions(cmd, c->args.run);
    cmd->callback([c] {
        applyThreads(c->args.run.threads);
        const pipeline::MeshSettings s = compareSettings(*c);
        const std::vector<std::string> outputs = compareOutputs(*c);
        // In a child process, as isohex mesh: a reader crashing on a damaged
        // scan is an error naming it (cli/Isolate.hpp).
        runIsolated(c->input, outputs, [&] {
            ProgressSink sink(c->args.run.progressMode());
            const pipeline::Prepared p = pipeline::prepare(c->input, s, sink);
            std::vector<Variant> variants = makeVariants(p, s, c->seed, sink);
            std::vector<HistogramSeries> series;
            nlohmann::json out = optimizeVariants(variants, p, s, *c, sink, series);
            out["versions"] = versionsJson();
            out["peak_memory_mb"] = peakMemoryMb();
            if (!c->json.empty()) writeJsonFile(out, c->json, c->args.run.force);
            if (!c->plot.empty())
                writeHistogramSvg(c->plot, c->args.run.force, "Scaled Jacobian per variant: " + c->input, series);
            return nlohmann::json::object();
        });
    });
}

}  // namespace isohex::cli

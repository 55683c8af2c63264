// isohex compare INPUT: the seed's experiment (section 5.3) in one command:
// the options parsed, the variants made and optimised by pipeline/Compare.hpp,
// their table printed and their JSON, histogram and meshes written.
#include <algorithm>
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
#include "isohex/core/Quality.hpp"
#include "isohex/pipeline/Compare.hpp"
#include "isohex/pipeline/MinQuality.hpp"
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
    std::string variants = "a,b,c,d";
    bool moveBoundary = false;
    MeshArgs args;
};

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

// --variants: some of a, b, c, d, comma-separated, each once.
std::vector<pipeline::CompareVariantKind> parseVariants(const std::string& text, std::string* why = nullptr) {
    std::vector<pipeline::CompareVariantKind> out;
    std::size_t start = 0;
    while (start <= text.size()) {
        const std::size_t comma = std::min(text.find(',', start), text.size());
        const std::string key = text.substr(start, comma - start);
        const auto kind = pipeline::variantOfKey(key);
        if (!kind || std::find(out.begin(), out.end(), *kind) != out.end()) {
            if (why) *why = kind ? "names " + key + " twice" : "has '" + key + "', which is not a, b, c or d";
            return {};
        }
        out.push_back(*kind);
        start = comma + 1;
    }
    return out;
}

CLI::Validator variantsValidator() {
    return CLI::Validator(
        [](const std::string& v) {
            std::string why;
            return parseVariants(v, &why).empty()
                       ? "--variants takes some of a, b, c, d separated by commas, e.g. a,b (got '" + v + "': it " +
                             why + ")"
                       : std::string();
        },
        "", "LIST");
}

// Compare's stages: the scan's, the variants' sheet operations (those the
// variants asked for need; the others are passed over), one optimisation per
// variant.
std::vector<std::string> comparePlan(const std::vector<pipeline::CompareVariantKind>& variants) {
    std::vector<std::string> plan = {"load", "select", "octree", "extract", "boundary_quads", "pillow", "dice",
                                     "extract sheets"};
    plan.insert(plan.end(), variants.size(), "optimize");
    return plan;
}

// Their shares of compare's time on skull_ct (15 s: the surface smoothing 7.3,
// dicing 2.0, the sheet extractions 3.2, each variant's optimisation 0.4-0.9).
// On larger meshes the extraction loop grows faster than the rest (ch2bet at
// 2 mm: 764 of 848 s), so the ETA there is low until it ends.
const std::map<std::string, double> kCompareWeights = {
    {"load", 1}, {"select", 1}, {"octree", 1}, {"extract", 1}, {"boundary_quads", 48}, {"pillow", 1},
    {"dice", 13}, {"extract sheets", 21}, {"optimize", 4}};

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
    // every variant aims at one target (a second one would be decided per variant)
    if (!s.worstHexTarget) s.worstHexTarget = pipeline::kDefaultWorstHexTarget;
    return s;
}

std::string variantMeshPath(const CompareArgs& c, const std::string& key) {
    return (std::filesystem::path(c.meshDir) / ("variant_" + key + ".vtu")).string();
}

// Every output, checked before the meshings (the variant meshes too);
// the folder of the variant meshes is made.
std::vector<std::string> compareOutputs(const CompareArgs& c) {
    std::vector<std::string> outputs;
    if (!c.json.empty()) outputs.push_back(c.json);
    if (!c.plot.empty()) outputs.push_back(c.plot);
    if (!c.meshDir.empty()) {
        std::error_code ec;
        std::filesystem::create_directories(c.meshDir, ec);
        if (ec) throw Error(c.meshDir + ": cannot create the folder for the variant meshes: " + ec.message());
        for (pipeline::CompareVariantKind k : parseVariants(c.variants))
            outputs.push_back(variantMeshPath(c, pipeline::variantKey(k)));
    }
    checkOutputPaths(outputs, {c.input}, c.args.run.force);
    return outputs;
}

// Optimises each variant by the protocol, prints its line of the table,
// writes its mesh (with --mesh-dir) and returns the comparison's JSON;
// `series` gets each variant's histogram.
nlohmann::json optimizeVariants(pipeline::CompareVariants& cv, const pipeline::Prepared& p,
                                const pipeline::MeshSettings& s, const CompareArgs& c, ProgressSink& sink,
                                std::vector<HistogramSeries>& series) {
    nlohmann::json out;
    out["input"] = pipeline::toJson(p.facts.input);
    out["grid"] = pipeline::toJson(p.facts.grid);
    out["protocol"] = s.fixBoundary ? "boundary quads smoothed on the isosurface once, before any sheet (every "
                                      "variant has the same surface mesh), then boundary nodes fixed, interior "
                                      "optimised (seed 5.2.2, 5.3)"
                                    : "boundary nodes slide on the isosurface";
    out["seed"] = c.seed;
    nlohmann::json quads;
    if (cv.boundaryQuads) quads = out["boundary_quads"] = pipeline::toJson(*cv.boundaryQuads);
    std::printf("%-44s %9s %8s %8s %8s %9s %8s\n", "variant", "hexes", "min SJ", "mean SJ", "<0.2", "inverted",
                "seconds");
    for (auto& v : cv.variants) {
        const std::string key = pipeline::variantKey(v.kind), label = pipeline::variantLabel(v.kind);
        sink.setJob("variant " + key);  // its warnings say which variant they are about
        const nlohmann::json opt = pipeline::toJson(pipeline::optimizeCompareVariant(v, p, s, sink));
        sink.setJob({});
        const HexQuality q = computeQuality(v.mesh);
        const QualitySummary qs = summarize(v.mesh, q);
        nlohmann::json j = toJson(qs);
        j["variant"] = key;
        j["label"] = label;
        j["operations"] = v.operations;
        j["optimization"] = opt;
        if (!quads.is_null()) j["boundary_quads"] = quads;  // the shared smoothing, under each variant too
        j["seconds"] = v.seconds;
        out["variants"].push_back(j);
        series.push_back({key + ": " + label, qs.histogram, qs.degenerate});
        std::printf("%-44s %9zu %8.3f %8.3f %8zu %9zu %8.1f\n", (key + ") " + label).c_str(), qs.hexes,
                    qs.scaledJacobian.min, qs.scaledJacobian.mean, qs.below02, qs.inverted, v.seconds);
        if (!c.meshDir.empty()) {
            io::WriteOptions w;
            w.overwrite = c.args.run.force;
            w.scaledJacobian = q.scaledJacobian;
            io::write(v.mesh, variantMeshPath(c, key), w);
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
    cmd->add_option("--variants", c->variants,
                    "Which variants to make, e.g. a,b (default a,b,c,d): c and d (random sheets diced in or "
                    "extracted) take most of the time on a large scan, and grow with the square of its size")
        ->check(variantsValidator());
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
            const std::vector<pipeline::CompareVariantKind> kinds = parseVariants(c->variants);
            ProgressSink sink(c->args.run.progressMode(), {}, comparePlan(kinds), kCompareWeights);
            const pipeline::Prepared p = pipeline::prepare(c->input, s, sink);
            pipeline::CompareVariants variants = pipeline::makeCompareVariants(p, s, c->seed, sink, kinds);
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

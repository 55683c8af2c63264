#include "isohex/pipeline/Estimate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>
#include <vector>

#include <tbb/parallel_for.h>

#include "isohex/core/SettingError.hpp"
#include "isohex/octree/GridEdits.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/pipeline/MemoryEstimate.hpp"

namespace isohex::pipeline {

namespace {

// The hexes of the labels sampled on the grid (before repair; with
// keepLargest only the largest regions): dual contouring
// makes one hex per labelled point; each sheet layer adds one hex per face
// between a labelled point and background, and two per face between two
// materials (every material gets its own sheet).
struct SampledHexes {
    double all = 0;  // on the whole grid (a part's: its window)
    double own = 0;  // of the points of a part's own slab (all, without a part)
};

// Whether the grid point (i, j, k) of the sampled grid lies in the part's own slab.
bool ownPoint(const std::optional<PartWindow>& w, int i, int j, int k) {
    if (!w) return true;
    const int layer = w->first + (w->axis == 0 ? i : w->axis == 1 ? j : k);
    return w->coreLo <= layer && layer < w->coreHi;
}

SampledHexes sampledHexes(const Prepared& p, const MeshSettings& settings) {
    octree::Labels labels = octree::sampleLabels(*p.domain, p.facts.grid.grid);
    if (settings.keepLargest) octree::keepLargestComponents(labels);
    const octree::Grid& g = labels.grid;
    const std::array<int, 3> d = g.dims;
    const double layers = settings.pillow ? double(std::max(settings.boundaryLayers, 1)) : 0.0;
    std::vector<SampledHexes> perSlice(static_cast<std::size_t>(d[2]));
    tbb::parallel_for(0, d[2], [&](int k) {
        for (int j = 0; j < d[1]; ++j)
            for (int i = 0; i < d[0]; ++i) {
                const std::int32_t m = labels.at(i, j, k);
                if (m == 0) continue;
                double hexes = 1;
                for (const auto& n : {std::array{i + 1, j, k}, std::array{i - 1, j, k}, std::array{i, j + 1, k},
                                      std::array{i, j - 1, k}, std::array{i, j, k + 1}, std::array{i, j, k - 1}}) {
                    const std::int32_t o = labels.at(n[0], n[1], n[2]);
                    if (o != m) hexes += layers;  // each face once per material on its sides
                }
                perSlice[std::size_t(k)].all += hexes;
                if (ownPoint(p.part, i, j, k)) perSlice[std::size_t(k)].own += hexes;
            }
    });
    SampledHexes total;
    for (const SampledHexes& s : perSlice) total.all += s.all, total.own += s.own;
    return total;
}

}  // namespace

double expectedCpuSeconds(double hexes, double voxels, const MeshSettings& settings, const TimeModel& model) {
    hexes = std::max(hexes, 0.0);
    if (!settings.optimize)
        return model.noOptimizeSeconds + model.noOptimizePerHex * hexes + model.noOptimizePerVoxel * voxels;
    return std::max(model.startSeconds,
                    model.cpuCoefficient * std::pow(hexes, model.cpuExponent) + model.cpuPerVoxel * voxels);
}

double expectedOutputBytes(double hexes, io::Format format) {
    double perHex = 0;
    switch (format) {
        case io::Format::Vtu: perHex = 122; break;
        case io::Format::Exodus: perHex = 69; break;
        case io::Format::Abaqus: perHex = 132; break;
        case io::Format::Medit: perHex = 120; break;
        case io::Format::Msh: perHex = 128; break;
    }
    return perHex * std::max(hexes, 0.0);
}

double expectedWallSeconds(double cpuSeconds, int threads, const TimeModel& model) {
    const double speedUp = 1.0 + model.extraThreadEfficiency * double(std::max(threads, 1) - 1);
    return model.startSeconds + std::max(cpuSeconds - model.startSeconds, 0.0) / speedUp;
}

int chooseThreads(double cpuSeconds, int maxThreads, double targetSeconds, const TimeModel& model) {
    const int most = std::max(maxThreads, 1);
    for (int t = 1; t < most; ++t)
        if (expectedWallSeconds(cpuSeconds, t, model) <= targetSeconds) return t;
    return most;
}

MeshEstimate estimateMesh(const std::string& input, const MeshSettings& settings, const EstimateOptions& options,
                          StageSink& sink, PreparedFacts* facts) {
    if (settings.method == Method::Sheets)
        throw SettingError({input + ": the ", Setting::Method,
                            " sheets has no grid to estimate from before meshing; estimate the dual method instead"});
    const Prepared p = prepareGrid(input, settings, sink);
    const MeshMemoryEstimate mem = estimateMeshMemory(*p.volume, *p.selection, p.facts.grid.grid, settings);
    MeshEstimate e;
    if (settings.meshExterior) {
        e.hexes = e.ownHexes = mem.hexes;
    } else {
        const SampledHexes sampled = sampledHexes(p, settings);
        e.hexes = sampled.all;
        e.ownHexes = sampled.own;
    }
    e.part = p.part;
    e.gridPoints = p.facts.grid.grid.size();
    e.loadedBytes = mem.already;
    e.peakBytes = meshPeakBytes(mem.already, e.hexes, double(e.gridPoints));
    // the voxels loaded: with --part, only the part's window
    e.cpuSeconds = expectedCpuSeconds(e.hexes, double(p.volume->box.volume()), settings);
    e.threadsChosen = options.threads <= 0;
    e.threads = e.threadsChosen ? chooseThreads(e.cpuSeconds, options.maxThreads, options.targetSeconds)
                                : options.threads;
    e.wallSeconds = expectedWallSeconds(e.cpuSeconds, e.threads);
    if (facts) *facts = p.facts;
    return e;
}

nlohmann::json toJson(const MeshEstimate& e, const PreparedFacts& facts) {
    constexpr double mb = 1024.0 * 1024.0;
    const octree::Grid& g = facts.grid.grid;
    nlohmann::json j;
    j["input"] = facts.input.path;
    j["dimensions"] = facts.input.dimensions;
    j["spacing"] = facts.input.spacing;
    if (facts.selection.iso) j["iso"] = *facts.selection.iso;
    j["element_size"] = g.spacing();
    j["grid_dimensions"] = g.dims;
    if (facts.grid.level) j["level"] = *facts.grid.level;
    j["grid_points"] = e.gridPoints;
    j["hexes"] = std::llround(e.hexes);
    j["loaded_memory_mb"] = std::ceil(e.loadedBytes / mb);
    j["peak_memory_mb"] = std::ceil(e.peakBytes / mb);
    nlohmann::json output;  // what the run writes: a part, its own slab
    for (const auto& [ext, format] : {std::pair{"vtu", io::Format::Vtu}, std::pair{"msh", io::Format::Msh},
                                      std::pair{"exo", io::Format::Exodus}, std::pair{"inp", io::Format::Abaqus},
                                      std::pair{"mesh", io::Format::Medit}})
        output[ext] = std::round(expectedOutputBytes(e.ownHexes, format) / mb * 100) / 100;
    j["output_mb"] = output;
    j["cpu_seconds"] = std::round(e.cpuSeconds * 10) / 10;
    j["wall_seconds"] = std::round(e.wallSeconds * 10) / 10;
    j["threads"] = e.threads;
    j["threads_chosen"] = e.threadsChosen;
    if (e.part)
        j["part"] = {{"index", e.part->spec.index},
                     {"count", e.part->spec.count},
                     {"axis", e.part->axis},
                     {"own_layers", {e.part->coreLo, e.part->coreHi}},
                     {"window_layers", {e.part->first, e.part->first + e.part->grid.dims[std::size_t(e.part->axis)]}},
                     {"own_hexes", std::llround(e.ownHexes)}};
    j["model"] = {{"hexes", "labels sampled on the grid: a hex per labelled point, + one per boundary face per sheet layer"},
                  {"memory", "peak after loading + 16 MB + 220 bytes per hex + 8 bytes per grid point"},
                  {"output", "bytes per hex per format measured by bench/output_sizes.py: vtu 122, msh 128, exo 69, "
                             "inp 132, mesh 120 (six inputs, each within 14%)"},
                  {"time", "fitted to bench/RESULTS.md by bench/fit_time_model.py: CPU s = 0.000304 hexes^0.840 + "
                           "4.01e-7 voxels, within a factor 1.93 with the sheet (up to 10 times more without it)"}};
    return j;
}

}  // namespace isohex::pipeline

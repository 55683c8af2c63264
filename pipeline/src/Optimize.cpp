#include "isohex/pipeline/Optimize.hpp"

#include <algorithm>
#include <tuple>
#include <utility>
#include <vector>

#include "isohex/pipeline/OptimizerProgress.hpp"
#include "Stage.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/octree/RepairedDomain.hpp"
#include "isohex/pipeline/FieldProjector.hpp"
#include "isohex/pipeline/MinQuality.hpp"
#include "isohex/pipeline/StuckHexes.hpp"

namespace isohex::pipeline {

WorstHexPassResult worstHexPass(HexMesh& mesh, const smoothing::SurfaceProjector* projector, double target,
                                double slack, const Topology* topo, const Progress& progress) {
    const Stopwatch clock;
    WorstHexPassResult r;
    r.options.target = target;
    r.options.surfaceSlack = slack;
    r.result = smoothing::raiseWorstHexes(mesh, projector, r.options, topo, progress);
    r.seconds = clock.seconds();
    return r;
}

namespace {

// The smallest and the mean scaled Jacobian (0, 0 without hexes).
std::pair<double, double> minAndMean(const std::vector<double>& sj) {
    if (sj.empty()) return {0, 0};
    double s = 0;
    for (double x : sj) s += x;
    return {*std::min_element(sj.begin(), sj.end()), s / static_cast<double>(sj.size())};
}

}  // namespace

StretchResult stretchWorstHexes(HexMesh& mesh, const smoothing::SurfaceProjector* projector, double target,
                                double slack, const Progress& progress) {
    StretchResult r;
    r.target = target;
    const std::vector<Vec3> start = mesh.nodes;
    std::tie(r.minBefore, r.meanBefore) = minAndMean(scaledJacobians(mesh));
    r.pass = worstHexPass(mesh, projector, target, slack, nullptr, progress);
    const auto [minAfter, meanAfter] = minAndMean(scaledJacobians(mesh));
    // (a minimum above the one before, itself at least the first target, means no hex is inverted)
    r.kept = minAfter > r.minBefore && meanAfter >= r.meanBefore - kStretchMeanLoss;
    if (!r.kept) mesh.nodes = start;
    r.minAfter = r.kept ? minAfter : r.minBefore;
    r.meanAfter = r.kept ? meanAfter : r.meanBefore;
    return r;
}

std::optional<StretchResult> stretchIfReached(HexMesh& mesh, const smoothing::SurfaceProjector* projector,
                                              double firstTarget, double reached, double stretch, double slack,
                                              const Progress& progress) {
    if (!(stretch > firstTarget && reached >= firstTarget && reached < stretch)) return std::nullopt;
    return stretchWorstHexes(mesh, projector, stretch, slack, progress);
}

smoothing::BoundaryQuadResult smoothBoundaryOnIsosurface(HexMesh& mesh, const Prepared& p, StageSink& sink) {
    Stage st(sink, "boundary_quads");
    const auto* domain = static_cast<const SelectionDomain*>(p.domain.get());
    const FieldProjector projector(*domain, mesh, static_cast<const octree::RepairedDomain*>(p.repairedDomain.get()));
    const smoothing::BoundaryQuadResult r =
        smoothing::smoothBoundaryQuads(mesh, projector, buildTopology(mesh, TopologyParts::NodeMoves));
    st.finish();
    return r;
}

OptimizeResult optimize(HexMesh& mesh, const Prepared& p, const MeshSettings& settings, StageSink& sink,
                        bool warnLeftInverted, OptimizeScope scope) {
    OptimizeResult r;
    r.enabled = settings.optimize;
    if (!settings.optimize) return r;
    Stage st(sink, "optimize");
    smoothing::SmoothingOptions opt;
    opt.fixBoundary = settings.fixBoundary;
    opt.offSurfaceNodesOntoSurface = !settings.tangledStart;
    if (scope == OptimizeScope::Neighbourhood) opt.relativeTolerance = 0;
    const auto* domain = static_cast<const SelectionDomain*>(p.domain.get());
    FieldProjector projector(*domain, mesh, static_cast<const octree::RepairedDomain*>(p.repairedDomain.get()));
    PhasedProgress phased = optimizerProgress(
        sink, settings.worstHexPass ? WorstHexesInStage::Yes : WorstHexesInStage::No);
    // The optimiser builds its own topology and keeps only the node-to-hex
    // rows of it while it runs; the worst-hex pass builds another. One shared
    // topology saved a build (about a second at 1.9 M hexes) and cost about
    // 130 bytes per hex at the job's peak, in the optimiser's release phase.
    r.smoothingResult = smoothing::optimizeMesh(mesh, settings.fixBoundary ? nullptr : &projector, opt, phased.callback());
    // The optimiser minimises a sum over all corners; the few hexes it leaves
    // poor (surface folds, spurs thinner than an element) get a max-min pass.
    if (settings.worstHexPass) {
        // The slack in world units: the tolerance is in voxels of the scan
        // (its smallest spacing), as the fidelity report measures.
        // (None with fixBoundary: surface nodes do not move at all.)
        const double voxels =
            settings.fixBoundary ? 0.0 : settings.surfaceTolerance.value_or(kDefaultSurfaceTolerance);
        const double slack = voxels * p.selection->materials.front().field.voxelSize();
        // aimed at the certified minimum when that is higher (--min-quality)
        r.worstHexes = worstHexPass(mesh, settings.fixBoundary ? nullptr : &projector,
                                    worstHexTargetFor(p.facts.input.path, settings), slack, nullptr, phased.callback());
        r.worstHexes->surfaceToleranceVoxels = voxels;
        r.stretch = stretchIfReached(mesh, settings.fixBoundary ? nullptr : &projector, r.worstHexes->options.target,
                                     r.worstHexes->result.minAfter, stretchTargetFor(p.facts.input.path, settings),
                                     slack, [&](std::string_view, double f) { phased.report("stretch", f); });
    }
    r.fixBoundary = settings.fixBoundary;
    // The warning counts what is still inverted after the worst-hex pass too
    // (which may fix some, and may trade one for another), at the first.
    // (runMeshPipeline counts and warns itself, after its retries.)
    if (warnLeftInverted && !r.smoothingResult.untangleFailures.empty())
        warnInverted(sink, mesh, invertedHexes(mesh), r.smoothingResult.untangleFailures.size(), "", settings.fixBoundary,
                     settings.fixBoundaryByCompare);
    st.finish();
    return r;
}

}  // namespace isohex::pipeline

#include "isohex/pipeline/FeatureRemoval.hpp"

#include <algorithm>
#include <map>
#include <memory>
#include <set>

#include "Format.hpp"
#include "Stage.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/Regions.hpp"
#include "isohex/octree/RepairedDomain.hpp"
#include "isohex/pipeline/LocalRetry.hpp"

namespace isohex::pipeline {

namespace {

// The worst scaled Jacobian (degenerate as 0) and the hexes below `target`, worst first.
struct Below {
    double min = 1;
    std::vector<Index> hexes;
};

Below belowOf(const HexMesh& mesh, double target) {
    const std::vector<double> sj = scaledJacobians(mesh);
    Below b;
    std::vector<std::pair<double, Index>> below;
    for (std::size_t h = 0; h < sj.size(); ++h) {
        const double v = scaledJacobianCollapsed(sj[h]) ? 0.0 : sj[h];
        b.min = std::min(b.min, v);
        if (belowTarget(sj[h], target)) below.emplace_back(v, static_cast<Index>(h));
    }
    std::sort(below.begin(), below.end());
    for (const auto& [v, h] : below) b.hexes.push_back(h);
    return b;
}

const octree::RepairedDomain* repairedOf(const Prepared& p) {
    return dynamic_cast<const octree::RepairedDomain*>(p.repairedDomain.get());
}

// The features next to the worst hexes below the target, each once, none
// sharing a grid point with an earlier one. A material's only piece is never
// a feature: the user asked for that material.
std::vector<FineFeature> featuresNear(const Meshing& m, const std::vector<Index>& below) {
    const LocalFeatures local(m.prepared.labels, repairedOf(m.prepared));
    std::map<std::int32_t, std::size_t> pointsOf;
    for (std::int32_t label : m.prepared.labels.material) ++pointsOf[label];
    std::vector<FineFeature> out;
    std::set<std::size_t> taken;
    for (std::size_t n = 0; n < below.size() && n < kMaxHexesForFeatures; ++n)
        for (FineFeature& f : local.featuresAt(hexCentre(m.mesh, below[n]))) {
            if (std::any_of(f.points.begin(), f.points.end(), [&](std::size_t p) { return taken.count(p) > 0; }))
                continue;
            if (f.points.size() == pointsOf[f.material]) continue;
            taken.insert(f.points.begin(), f.points.end());
            out.push_back(std::move(f));
        }
    return out;
}

// The labels with the features given the label around them, repaired, on
// the field repaired for them.
Prepared withoutFeatures(const Prepared& p, const std::vector<FineFeature>& features, std::size_t& repairedPoints) {
    Prepared q = p;
    for (const FineFeature& f : features)
        for (std::size_t pt : f.points) q.labels.material[pt] = f.replacedBy;
    const octree::RepairReport repair = octree::repairNonManifold(q.labels, *p.domain);
    q.facts.grid.repair.report.pointsAdded += repair.pointsAdded;
    q.facts.grid.repair.report.pointsRemoved += repair.pointsRemoved;
    const octree::Labels sampled = octree::sampleLabels(*p.domain, q.labels.grid);
    auto repaired = std::make_shared<octree::RepairedDomain>(*p.domain, sampled, q.labels);
    repairedPoints = repaired->changedPoints();
    q.repairedDomain = std::move(repaired);
    q.facts.grid.topology = octree::regionTopology(q.labels);
    return q;
}

// One meshing without the features, relaxed, and what is left below the target.
struct Candidate {
    Meshing meshing;
    std::optional<RelaxationResult> relaxation;
    Below below;
    std::optional<RetryRegion> region;  // with local meshing
};

// Meshes `q` (best's labels without the features) again: only within
// `cells` grid cells of the `changed` grid points, the rest keeping best's
// optimised nodes (its node keys set), or the whole volume (kWholeVolume).
Candidate meshWithout(const Meshing& best, const Prepared& q, const std::vector<std::size_t>& changed, int cells,
                      const MeshSettings& settings, StageSink& sink, double target) {
    Candidate c;
    if (cells == kWholeVolume) {
        c.meshing = meshLabels(q, settings, sink);
    } else {
        LocalRegion region;
        c.meshing = meshLabelsNear(q, settings, sink, best, changed, cells, region);
        c.region = regionRecord(region);
    }
    c.relaxation = relaxToMinQuality(c.meshing.mesh, c.meshing.prepared, settings, sink);
    c.below = belowOf(c.meshing.mesh, target);
    return c;
}

bool better(const Below& after, const Below& before) {
    return after.min > before.min || (after.min == before.min && after.hexes.size() < before.hexes.size());
}

}  // namespace

std::optional<FeatureRemovalResult> removeFineFeatures(Meshing& best, const MeshSettings& given, StageSink& sink,
                                                       std::optional<RelaxationResult>& relaxation) {
    // the uniform mesh --adaptive kept (AdaptiveContour.hpp, keepTree) is
    // treated as the uniform mesher's, its adaptive facts kept
    const bool uniformKept = best.adaptive && best.adaptive->uniformKept;
    MeshSettings settings = given;
    if (uniformKept) settings.adaptive = false;
    if (!settings.optimize || !settings.removeFeatures || settings.method != Method::Dual || best.prepared.part ||
        (best.adaptive && !uniformKept))
        return std::nullopt;
    const double target = minQualityFor(best.prepared.facts.input.path, settings);
    const Below before = belowOf(best.mesh, target);
    if (before.hexes.empty()) return std::nullopt;
    const Stopwatch clock;
    FeatureRemovalResult r;
    r.minBefore = r.minAfter = before.min;
    r.belowBefore = r.belowAfter = before.hexes.size();
    const std::vector<FineFeature> features = featuresNear(best, before.hexes);
    if (features.empty()) {
        r.notMeshedBecause = "no speck, pocket, strand or tunnel finer than an element next to the hexes below " +
                             shortNumber(target);
        r.seconds = clock.seconds();
        return r;
    }
    for (const FineFeature& f : features)
        r.features.push_back({f.shape, f.material, f.replacedBy, f.at, f.volume, f.points.size()});
    sink.note("info", "meshing again without " + std::to_string(features.size()) +
                          " feature(s) finer than an element next to the hexes below " + shortNumber(target));
    // As the retries do it: the near neighbourhood of the changed points,
    // then the wide one, then (the last resort) the whole volume, until one
    // is better.
    const bool local = localRetryApplies(best, settings);
    std::optional<Candidate> c;
    try {
        const Prepared q = withoutFeatures(best.prepared, features, r.repairedPoints);
        const std::vector<std::size_t> changed = changedPoints(best.prepared.labels, q.labels);
        for (int cells : remeshScopes(local)) {
            c = meshWithout(best, q, changed, cells, settings, sink, target);
            if (better(c->below, before)) break;
        }
    } catch (const Error& e) {
        r.notMeshedBecause = std::string("the labels without them could not be meshed: ") + e.what();
        r.seconds = clock.seconds();
        return r;
    }
    r.region = c->region;
    r.minAfter = c->below.min;
    r.belowAfter = c->below.hexes.size();
    r.kept = better(c->below, before);
    if (r.kept) {
        Meshing& again = c->meshing;
        again.contouredHexes = again.mesh.hexCount();
        again.contouredNodes = again.mesh.nodeCount();
        if (uniformKept) {
            again.adaptive = std::move(best.adaptive);
            again.adaptive->hexLevel.assign(again.mesh.hexCount(), 0);
        }
        best = std::move(again);
        relaxation = std::move(c->relaxation);
    }
    r.seconds = clock.seconds();
    return r;
}

}  // namespace isohex::pipeline

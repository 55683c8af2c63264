#include "isohex/pipeline/FeatureRemoval.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <set>

#include "Format.hpp"
#include "Stage.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/octree/GridEdits.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/Regions.hpp"
#include "isohex/octree/RepairedDomain.hpp"
#include "isohex/pipeline/GridPositions.hpp"
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

// `q` (p with some labels changed), repaired, on the field repaired for it.
Prepared repairedAfterEdits(Prepared q, const Prepared& p, std::size_t& repairedPoints) {
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

// The labels with the features given the label around them, repaired, on
// the field repaired for them.
Prepared withoutFeatures(const Prepared& p, const std::vector<FineFeature>& features, std::size_t& repairedPoints) {
    Prepared q = p;
    for (const FineFeature& f : features)
        for (std::size_t pt : f.points) q.labels.material[pt] = f.replacedBy;
    return repairedAfterEdits(std::move(q), p, repairedPoints);
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

// Meshes `q` (best's labels edited) again in each scope in turn (grid cells
// around the changed points, or kWholeVolume) until one is better than `now`;
// the last one tried.
Candidate firstBetter(const Meshing& best, const Prepared& q, const std::vector<int>& scopes, const Below& now,
                      const MeshSettings& settings, StageSink& sink, double target) {
    const std::vector<std::size_t> changed = changedPoints(best.prepared.labels, q.labels);
    std::optional<Candidate> c;
    for (int cells : scopes) {
        c = meshWithout(best, q, changed, cells, settings, sink, target);
        if (better(c->below, now)) break;
    }
    return std::move(*c);
}

// Makes the candidate's meshing the best one (the uniform mesh --adaptive
// kept stays marked as such, every hex at level 0).
void adopt(Meshing& best, Candidate& c, std::optional<RelaxationResult>& relaxation) {
    Meshing& again = c.meshing;
    again.contouredHexes = again.mesh.hexCount();
    again.contouredNodes = again.mesh.nodeCount();
    if (best.adaptive && best.adaptive->uniformKept) {
        again.adaptive = std::move(best.adaptive);
        again.adaptive->hexLevel.assign(again.mesh.hexCount(), 0);
    }
    best = std::move(again);
    relaxation = std::move(c.relaxation);
}

// The hexes below the target at label junctions (BelowCause::LabelJunction),
// worst first, at most kMaxStuckToRetry.
std::vector<Index> junctionHexes(const HexMesh& mesh, const Below& below) {
    std::vector<Index> out;
    for (Index h : below.hexes)
        if (out.size() < kMaxStuckToRetry && causeOf(mesh, h) == BelowCause::LabelJunction) out.push_back(h);
    return out;
}

// The report's entries for junction points given another label.
void recordJunctionPoints(const octree::Grid& g, const std::vector<octree::PointEdit>& edits, FeatureRemovalResult& r) {
    for (const octree::PointEdit& e : edits) {
        const auto [i, j, k] = g.coords(e.point);
        r.features.push_back({LocalShape::TripleLine, e.from, e.to, g.point(i, j, k), std::abs(g.determinant()), 1});
    }
}

// One round of junction edits (see removeFineFeatures): the most exposed grid
// point next to each hex below the target at a label junction takes the
// label most of its face neighbours hold, where that changes no label's
// components, tunnels or cavities (octree::editNearInvertedHexes), and the
// labels are meshed again around the edits: the near neighbourhood, then the
// wide one, never the whole volume (a round is one point per place, and up to
// three rounds of the whole volume would cost a large label map minutes).
// Keeps the result in `best` (and `now`, `relaxation`) and returns true when
// its worst hex is better.
bool junctionRound(Meshing& best, Below& now, const MeshSettings& settings, StageSink& sink, double target,
                   std::vector<std::size_t>& frozen, FeatureRemovalResult& r,
                   std::optional<RelaxationResult>& relaxation) {
    const std::vector<Index> work = junctionHexes(best.mesh, now);
    if (work.empty() || !localRetryApplies(best, settings)) return false;
    Prepared q = best.prepared;
    const std::vector<octree::PointEdit> edits =
        octree::editNearInvertedHexes(q.labels, hexCentresInGrid(best.mesh, q.labels.grid, work), frozen);
    if (edits.empty()) return false;
    for (const octree::PointEdit& e : edits) frozen.push_back(e.point);
    sink.note("info", "meshing again with " + std::to_string(edits.size()) +
                          " grid point(s) at label junctions next to the hexes below " + shortNumber(target) +
                          " given the label around them");
    std::size_t repairedPoints = 0;
    const Prepared edited = repairedAfterEdits(std::move(q), best.prepared, repairedPoints);
    Candidate c = firstBetter(best, edited, {kLocalRetryCells, kWideRetryCells}, now, settings, sink, target);
    if (!better(c.below, now)) return false;
    recordJunctionPoints(edited.labels.grid, edits, r);
    r.repairedPoints += repairedPoints;
    r.region = c.region;
    now = std::move(c.below);
    adopt(best, c, relaxation);
    return true;
}

// The features finer than an element next to the hexes below the target,
// given the label around them and meshed again (the near neighbourhood of the
// changed points, then the wide one, then the whole volume, until one is
// better, as the retries do); kept when better.
void removeFeatures(Meshing& best, Below& now, const MeshSettings& settings, StageSink& sink, double target,
                    FeatureRemovalResult& r, std::optional<RelaxationResult>& relaxation) {
    const std::vector<FineFeature> features = featuresNear(best, now.hexes);
    if (features.empty()) {
        r.notMeshedBecause = "no speck, pocket, strand or tunnel finer than an element next to the hexes below " +
                             shortNumber(target);
        return;
    }
    for (const FineFeature& f : features)
        r.features.push_back({f.shape, f.material, f.replacedBy, f.at, f.volume, f.points.size()});
    sink.note("info", "meshing again without " + std::to_string(features.size()) +
                          " feature(s) finer than an element next to the hexes below " + shortNumber(target));
    std::optional<Candidate> c;
    try {
        const Prepared q = withoutFeatures(best.prepared, features, r.repairedPoints);
        c = firstBetter(best, q, remeshScopes(localRetryApplies(best, settings)), now, settings, sink, target);
    } catch (const Error& e) {
        r.notMeshedBecause = std::string("the labels without them could not be meshed: ") + e.what();
        return;
    }
    r.region = c->region;
    if (!better(c->below, now)) return;  // (listed as tried; the mesh keeps them)
    r.kept = true;
    now = std::move(c->below);
    adopt(best, *c, relaxation);
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
    Below now = belowOf(best.mesh, target);
    if (now.hexes.empty()) return std::nullopt;
    const Stopwatch clock;
    FeatureRemovalResult r;
    r.minBefore = now.min;
    r.belowBefore = now.hexes.size();
    removeFeatures(best, now, settings, sink, target, r, relaxation);
    // Then the label junctions, round by round while the worst hex gets better.
    std::vector<std::size_t> frozen;
    try {
        for (int round = 0; round < kJunctionEditRounds && !now.hexes.empty(); ++round) {
            if (!junctionRound(best, now, settings, sink, target, frozen, r, relaxation)) break;
            r.kept = true;
        }
    } catch (const Error& e) {
        if (!r.notMeshedBecause)
            r.notMeshedBecause = std::string("the labels with junction points changed could not be meshed: ") + e.what();
    }
    r.minAfter = now.min;
    r.belowAfter = now.hexes.size();
    r.seconds = clock.seconds();
    return r;
}

}  // namespace isohex::pipeline

#include "isohex/pipeline/MinQuality.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>

#include "Format.hpp"
#include "isohex/core/NodeRings.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/Submesh.hpp"
#include "Stage.hpp"
#include "isohex/imaging/SurfaceVolume.hpp"
#include "isohex/octree/RepairedDomain.hpp"
#include "isohex/pipeline/FieldProjector.hpp"
#include "isohex/pipeline/StuckHexes.hpp"
#include "isohex/smoothing/NodePlace.hpp"
#include "isohex/smoothing/WorstHexes.hpp"

namespace isohex::pipeline {

const char* causeText(BelowCause cause) {
    switch (cause) {
        case BelowCause::LabelJunction: return "label junction";
        case BelowCause::ThinFeature: return "feature thinner than an element";
        case BelowCause::BoundaryPinned: return "boundary node pinned to the isosurface";
        case BelowCause::Interior: return "interior hex no node placement lifts";
        case BelowCause::NotOptimised: return "not optimised (--no-optimize leaves the hexes as extracted)";
    }
    return "interior hex no node placement lifts";
}

double minQualityFor(const std::string& input, const MeshSettings& settings) {
    if (settings.minQuality) return *settings.minQuality;
    if (settings.method == Method::Sheets) return kDefaultMinQualitySheetMethod;
    if (imaging::isSurfaceFile(input)) return kDefaultMinQualitySurface;
    if (!settings.optimize || settings.fixBoundary) return kDefaultMinQualityWithoutMeans;
    return settings.load.labels ? kDefaultMinQualityLabelMap : kDefaultMinQualityIntensity;
}

double maxDeviationFor(const std::string& input, const MeshSettings& settings) {
    if (settings.maxDeviation) return *settings.maxDeviation;
    return settings.load.labels && !imaging::isSurfaceFile(input) ? kDefaultMaxDeviationLabelMap
                                                                   : kDefaultMaxDeviation;
}

double worstHexTargetFor(const std::string& input, const MeshSettings& settings) {
    return std::max(settings.worstHexTarget.value_or(kDefaultWorstHexTarget), minQualityFor(input, settings));
}

double stretchTargetFor(const std::string& input, const MeshSettings& settings) {
    if (settings.worstHexTarget || settings.minQuality || settings.method == Method::Sheets || settings.fixBoundary)
        return 0;
    return kStretchTarget > worstHexTargetFor(input, settings) ? kStretchTarget : 0;
}

namespace {

// How far node v of `mesh` is from each place it belongs to (its surface or
// curve, or a junction node's surfaces: distancesFromPlace), 0 where a
// projection fails; none for a surface the projector leaves alone or a curve
// it does not know.
std::vector<double> offPlaces(const HexMesh& mesh, const smoothing::SurfaceProjector& projector,
                              const smoothing::JunctionSurfaces& junctions, Index v) {
    const NodeClass& c = mesh.nodeClass[static_cast<std::size_t>(v)];
    if (c.kind == NodeKind::Surface && !projector.projectsOnto(c.id)) return {};
    if (c.kind == NodeKind::Curve && c.id >= 0 && !projector.hasCurves()) return {};
    std::vector<double> d =
        smoothing::distancesFromPlace(mesh, projector, junctions, v, mesh.nodes[static_cast<std::size_t>(v)]);
    for (double& e : d)
        if (!std::isfinite(e)) e = 0;
    return d;
}

// The farthest a node now is from one of its places, over the places it got
// farther from than it was (`was`, 0 where not given); 0 if none.
double fartherOff(const std::vector<double>& now, const std::vector<double>& was) {
    double grew = 0;
    for (std::size_t i = 0; i < now.size(); ++i)
        if (now[i] > (i < was.size() ? was[i] : 0.0)) grew = std::max(grew, now[i]);
    return grew;
}


// Whether a hex (`sj`: scaledJacobians of the mesh) is below `target` as
// certifyQuality counts: below it, not positive, or degenerate.
bool anyBelow(const std::vector<double>& sj, double target) {
    return std::any_of(sj.begin(), sj.end(), [&](double v) { return belowTarget(v, target); });
}

// The surface, curve and junction nodes off one of their places (released to
// untangle, held back at extraction; a junction node off all but one of its
// surfaces), with those distances, ascending: a node the relaxation moves
// counts where it went farther from one. Sparse: a few dozen surface nodes
// of two million on a brain at 1 mm, and a label map's curve and junction
// nodes; no copy of every node is kept across the pass.
using OffPlaces = std::vector<std::pair<Index, std::vector<double>>>;
OffPlaces offPlacesOf(const HexMesh& mesh, const smoothing::SurfaceProjector& projector,
                      const smoothing::JunctionSurfaces& junctions) {
    OffPlaces off;
    for (std::size_t v = 0; v < mesh.nodes.size(); ++v)
        if (mesh.nodeClass[v].kind == NodeKind::Surface || mesh.nodeClass[v].kind == NodeKind::Curve) {
            std::vector<double> d = offPlaces(mesh, projector, junctions, static_cast<Index>(v));
            if (std::any_of(d.begin(), d.end(), [](double e) { return e > 0; }))
                off.emplace_back(static_cast<Index>(v), std::move(d));
        }
    return off;
}

// Rings of hexes whose nodes relaxRegion adds around the nodes a
// relaxation moves first. Its mean rounds then move nodes near moved ones; on
// the JHU labels at 4 mm the nodes it moved reached past one ring, and past
// two in a second relaxation there.
constexpr int kRelaxableRings = 3;

// Where a relaxation aimed at `aim` works: `free` flags the nodes of the
// hexes below the aim and the nodes off their places (which its return step
// moves), with every node within kRelaxableRings rings of hexes around them.
// The relaxation runs on the submesh of those nodes (cutOut): over the whole
// mesh, a pass built the whole topology and scanned every hex and node each
// round (at a million hexes 0.2 s of the stage's 1.1). `outsideMin`: the
// smallest scaled Jacobian of the hexes with no free node, which it leaves
// as they are (all at or above the aim; infinity if there are none).
struct RelaxRegion {
    std::vector<std::uint8_t> free;
    double outsideMin = std::numeric_limits<double>::infinity();
};

RelaxRegion relaxRegion(const HexMesh& mesh, const std::vector<double>& sj, double aim, const OffPlaces& off) {
    std::vector<std::uint8_t> seeds(mesh.nodes.size(), 0);
    for (std::size_t h = 0; h < sj.size(); ++h)
        if (belowTarget(sj[h], aim))
            for (Index v : mesh.hexes[h]) seeds[static_cast<std::size_t>(v)] = 1;
    for (const auto& entry : off) seeds[static_cast<std::size_t>(entry.first)] = 1;
    RelaxRegion r;
    r.free = nodesWithinRings(mesh, std::move(seeds), kRelaxableRings);
    for (std::size_t h = 0; h < sj.size(); ++h) {
        const Hex& hex = mesh.hexes[h];
        if (std::none_of(hex.begin(), hex.end(), [&](Index v) { return r.free[static_cast<std::size_t>(v)] != 0; }))
            r.outsideMin = std::min(r.outsideMin, sj[h]);
    }
    return r;
}

// One max-min pass of the relaxation, its compass search starting with steps
// of `firstStep` local edge lengths.
smoothing::WorstHexResult relaxOnce(HexMesh& mesh, const smoothing::SurfaceProjector& projector, double q,
                                    double target, double maxDeviation, double firstStep) {
    smoothing::WorstHexOptions o;
    o.target = target;
    o.reportBelow = q;  // the report counts hexes below Q, not below the aim
    o.surfaceSlack = maxDeviation;
    o.firstStep = firstStep;
    // Only the nodes of the hexes below the target move, and then, in the
    // mean rounds, the nodes next to them, each as far as no hex goes below
    // the target: a move that lifts one hex lowers its neighbours (down to
    // the target), and the mean rounds give that back where it was taken.
    o.meanOnlyNearMoved = true;
    // surface nodes leave their surface by the slack alone: no release of
    // inverted hexes' nodes by edge lengths, no joint moves (the optimiser
    // and its pass had those)
    o.releaseDistance = 0;
    o.jointRings = 0;
    o.listMovedNodes = true;
    return smoothing::raiseWorstHexes(mesh, &projector, o);
}

// Whether a hex of the submesh below q has a curve or junction node
// (BelowCause::LabelJunction), by the classes the nodes have in the whole
// mesh (the submesh's own make its border nodes Fixed).
bool belowAtJunction(const Submesh& s, const HexMesh& whole, double q) {
    const std::vector<double> sj = scaledJacobians(s.mesh);
    for (std::size_t h = 0; h < sj.size(); ++h) {
        if (!belowTarget(sj[h], q)) continue;
        for (Index v : s.mesh.hexes[h]) {
            const NodeKind k = whole.nodeClass[static_cast<std::size_t>(s.from[static_cast<std::size_t>(v)])].kind;
            if (k == NodeKind::Curve || k == NodeKind::Fixed) return true;
        }
    }
    return false;
}

// The relaxation of the submesh `s` of `whole`, aimed at `aim`, from
// kRelaxationFirstSteps[0]; then, while its minimum stays below q at a
// junction of labels, from each further step, every pass from the same
// start, the best kept (highest minimum, then fewest hexes below the aim). A
// mesh without curve nodes (one material) gets the one pass. `passes` and
// `firstStep`: the passes run and the kept one's first step.
smoothing::WorstHexResult relaxFromEachStep(Submesh& s, const HexMesh& whole,
                                            const smoothing::SurfaceProjector& projector, double q, double aim,
                                            double maxDeviation, int& passes, double& firstStep) {
    passes = 1;
    firstStep = kRelaxationFirstSteps[0];
    const std::vector<Vec3> start = s.mesh.nodes;
    smoothing::WorstHexResult best = relaxOnce(s.mesh, projector, q, aim, maxDeviation, kRelaxationFirstSteps[0]);
    for (std::size_t k = 1; k < kRelaxationFirstSteps.size(); ++k) {
        if (best.minAfter >= q || !belowAtJunction(s, whole, q)) break;
        std::vector<Vec3> kept = s.mesh.nodes;
        s.mesh.nodes = start;
        smoothing::WorstHexResult again = relaxOnce(s.mesh, projector, q, aim, maxDeviation, kRelaxationFirstSteps[k]);
        const bool better = again.minAfter > best.minAfter ||
                            (again.minAfter == best.minAfter && again.belowAfter < best.belowAfter);
        ++passes;
        if (better) {
            best = std::move(again);
            firstStep = kRelaxationFirstSteps[k];
        } else {
            s.mesh.nodes = std::move(kept);
        }
    }
    return best;
}

}  // namespace

BelowCause causeOf(const HexMesh& mesh, Index h) {
    int onSurface = 0;
    bool junction = false;
    for (Index v : mesh.hexes[static_cast<std::size_t>(h)]) {
        const NodeKind k = mesh.nodeClass[static_cast<std::size_t>(v)].kind;
        if (k == NodeKind::Curve || k == NodeKind::Fixed) junction = true;
        if (k != NodeKind::Interior) ++onSurface;
    }
    if (junction) return BelowCause::LabelJunction;
    if (onSurface == 8) return BelowCause::ThinFeature;
    if (onSurface > 0) return BelowCause::BoundaryPinned;
    return BelowCause::Interior;
}

RelaxationResult relaxBoundary(HexMesh& mesh, const std::vector<double>& sj, const smoothing::SurfaceProjector& projector,
                               double q, double maxDeviation, double tolerance, double voxel) {
    const Stopwatch clock;
    RelaxationResult r;
    r.maxDeviationVoxels = maxDeviation / voxel;
    const smoothing::JunctionSurfaces junctions = smoothing::junctionSurfaces(mesh);
    const OffPlaces offBefore = offPlacesOf(mesh, projector, junctions);
    const double aim = std::min(1.0, q + kRelaxationMargin);
    const RelaxRegion region = relaxRegion(mesh, sj, aim, offBefore);
    Submesh s = cutOut(mesh, region.free);
    r.regionHexes = s.mesh.hexCount();
    const smoothing::WorstHexResult w =
        relaxFromEachStep(s, mesh, projector, q, aim, maxDeviation, r.passes, r.firstStep);
    putBack(s, mesh);
    r.nodesMoved = w.nodesMoved;
    // (the hexes below the aim, and so the smallest, are all in the submesh)
    r.minBefore = std::min(w.minBefore, region.outsideMin);
    r.minAfter = std::min(w.minAfter, region.outsideMin);
    r.belowBefore = w.reportedBelowBefore;
    r.belowAfter = w.reportedBelowAfter;
    const std::vector<double> none;
    for (Index moved : w.movedNodes) {
        const Index v = s.from[static_cast<std::size_t>(moved)];
        const auto it = std::lower_bound(offBefore.begin(), offBefore.end(), v,
                                         [](const auto& entry, Index u) { return entry.first < u; });
        const std::vector<double>& was = it != offBefore.end() && it->first == v ? it->second : none;
        const double d = fartherOff(offPlaces(mesh, projector, junctions, v), was);
        if (!(d > 0)) continue;
        r.largestDeviationVoxels = std::max(r.largestDeviationVoxels, d / voxel);
        if (d > tolerance) ++(mesh.nodeClass[static_cast<std::size_t>(v)].kind == NodeKind::Curve ? r.curveNodesOff : r.nodesOff);
    }
    r.seconds = clock.seconds();
    return r;
}

bool relaxesBoundary(const MeshSettings& settings) {
    return settings.optimize && !settings.fixBoundary && settings.worstHexPass && settings.method == Method::Dual;
}

std::optional<RelaxationResult> relaxToMinQuality(HexMesh& mesh, const Prepared& p, const MeshSettings& settings,
                                                  StageSink& sink) {
    if (!relaxesBoundary(settings)) return std::nullopt;
    const double tolerance = settings.surfaceTolerance.value_or(kDefaultSurfaceTolerance);
    const double maxDeviation = maxDeviationFor(p.facts.input.path, settings);
    if (!(maxDeviation > tolerance)) return std::nullopt;
    const double target = minQualityFor(p.facts.input.path, settings);
    const std::vector<double> sj = scaledJacobians(mesh);
    if (!anyBelow(sj, target)) return std::nullopt;
    Stage st(sink, "relax");
    const auto* domain = static_cast<const SelectionDomain*>(p.domain.get());
    const FieldProjector projector(*domain, mesh, static_cast<const octree::RepairedDomain*>(p.repairedDomain.get()));
    const double voxel = p.selection->materials.front().field.voxelSize();
    RelaxationResult r = relaxBoundary(mesh, sj, projector, target, maxDeviation * voxel, tolerance * voxel, voxel);
    r.target = target;
    st.finish();
    return r;
}

QualityCertificate certifyQuality(const HexMesh& mesh, double target, const LocalFeatures* local, bool optimised) {
    QualityCertificate c;
    c.target = target;
    const std::vector<double> sj = scaledJacobians(mesh);
    std::vector<std::pair<double, Index>> below;
    double sum = 0;
    std::size_t counted = 0;
    c.achieved = sj.empty() ? 0.0 : 1.0;
    for (std::size_t h = 0; h < sj.size(); ++h) {
        const bool degenerate = scaledJacobianCollapsed(sj[h]);  // Verdict's 1e30: a collapsed edge
        const double v = degenerate ? 0.0 : sj[h];
        c.achieved = std::min(c.achieved, v);
        if (!degenerate) {
            sum += v;
            ++counted;
            const auto* it = std::upper_bound(kScaledJacobianBins.begin(), kScaledJacobianBins.end(), v);
            ++c.histogram[static_cast<std::size_t>(std::clamp<long>(it - kScaledJacobianBins.begin() - 1, 0, 10))];
        }
        if (belowTarget(sj[h], target)) below.emplace_back(v, static_cast<Index>(h));
    }
    if (local) {
        c.belowByShape.emplace();
        c.belowByShape->fill(0);
        for (const auto& [v, h] : below) ++(*c.belowByShape)[static_cast<std::size_t>(local->shapeAt(hexCentre(mesh, h)))];
    }
    c.mean = counted ? sum / static_cast<double>(counted) : 0.0;
    c.hexesBelow = below.size();
    c.certified = below.empty() && !sj.empty();
    std::sort(below.begin(), below.end());
    if (below.size() > kMaxPlacesListed) below.resize(kMaxPlacesListed);
    for (const auto& [v, h] : below) {
        const Vec3 at = hexCentre(mesh, h);
        c.places.push_back({at, mesh.material[static_cast<std::size_t>(h)], v,
                            optimised ? causeOf(mesh, h) : BelowCause::NotOptimised, std::nullopt});
        if (local) c.places.back().shape = local->shapeAt(at);
    }
    return c;
}

std::string describePlaces(const QualityCertificate& c, std::size_t lines) {
    std::string s;
    for (std::size_t i = 0; i < c.places.size() && i < lines; ++i) {
        const BelowPlace& p = c.places[i];
        s += "  at (" + shortNumber(p.at[0]) + ", " + shortNumber(p.at[1]) + ", " + shortNumber(p.at[2]) +
             "), material " + std::to_string(p.material) + ", scaled Jacobian " + shortNumber(p.scaledJacobian) +
             ": " + causeText(p.cause) + "\n";
    }
    const std::size_t shown = std::min(lines, c.places.size());
    if (c.hexesBelow > shown)
        s += "  and " + std::to_string(c.hexesBelow - shown) + " more hex(es) below " + shortNumber(c.target) +
             " (the report's quality.places lists " + std::to_string(c.places.size()) + ")\n";
    return s;
}

}  // namespace isohex::pipeline

// Whole-mesh smoothing (optimizeMesh, untangle): the smoother's phases in
// order, the mean-ratio sweeps and the whole-mesh figures.
#include "isohex/smoothing/Optimize.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <functional>
#include <string>

#include <tbb/parallel_reduce.h>

#include "Smoother.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/smoothing/SweepProgress.hpp"

namespace isohex::smoothing {

namespace detail {

namespace {

ObjectiveSum objectiveSum(const HexMesh& mesh) {
    return blockSum(mesh.hexCount(), [&](std::size_t h) { return inverseMeanRatio(hexCoords(mesh, static_cast<Index>(h))); });
}

// Hexes with a corner or centre determinant <= 0 (or not a number).
std::size_t invertedCount(const HexMesh& mesh) {
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, mesh.hexCount(), kBlock), std::size_t{0},
        [&](const auto& r, std::size_t n) {
            for (std::size_t h = r.begin(); h != r.end(); ++h)
                n += !(minJacobianDeterminant(hexCoords(mesh, static_cast<Index>(h))) > 0);
            return n;
        },
        std::plus<>());
}

}  // namespace

void Smoother::refreshHexStates() {
    const std::size_t H = mesh_.hexCount(), N = mesh_.nodeCount();
    auto evaluate = [&](std::size_t h) {
        const HexCoords x = hexCoords(mesh_, static_cast<Index>(h));
        hexImr_[h] = inverseMeanRatio(x);
        hexInverted_[h] = !(minJacobianDeterminant(x) > 0);
    };
    std::vector<std::uint8_t> dirty;
    if (!hexStatesReady_) {
        hexImr_.resize(H);
        hexInverted_.resize(H);
        dirty.assign(H, 1);
        hexStatesReady_ = true;
    } else {
        dirty.assign(H, 0);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, N, kBlock), [&](const auto& r) {
            for (std::size_t v = r.begin(); v != r.end(); ++v)
                if (nodeMoved_[v])
                    for (const Index* h = topo_.nodeHexes.begin(v); h != topo_.nodeHexes.end(v); ++h)
                        raise(dirty[static_cast<std::size_t>(*h)]);
        });
    }
    std::fill(nodeMoved_.begin(), nodeMoved_.end(), std::uint8_t{0});
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H, kBlock), [&](const auto& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h)
            if (dirty[h]) evaluate(h);
    });
}

// Released nodes, one at a time in index order (few, and deterministic):
// the largest step towards their projection, of 1, 1/2, ... 1/64, that keeps
// every corner around them positive.
void Smoother::returnToSurface() {
    auto& buf = buffers_->local();
    for (std::size_t v = 0; v < released_.size(); ++v) {
        if (!released_[v]) continue;
        if (mode_[v] == Mode::Curve && !projector_->hasCurves()) continue;  // nowhere to return to
        const Vec3& x = mesh_.nodes[v];
        const Vec3 y = mode_[v] == Mode::Curve ? projector_->projectToCurve(mesh_.nodeClass[v].id, x)
                                               : projector_->project(mesh_.nodeClass[v].id, x);
        const Vector3 full(y[0] - x[0], y[1] - x[1], y[2] - x[2]);
        if (!full.allFinite()) continue;
        const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, static_cast<Index>(v), buf.data());
        NodeObjective<InverseMeanRatio> objective(InverseMeanRatio{}, buf.data(), n);
        double t = 1.0;
        for (int k = 0; k <= 6; ++k, t *= 0.5)
            if (std::isfinite(objective.value(t * full))) {
                moveNode(v, k == 0 ? y : displaced(x, t * full));
                if (k == 0) released_[v] = 0;
                break;
            }
    }
}

std::vector<std::uint8_t> Smoother::initialActive(bool onlyTouched, std::vector<std::uint8_t>& next) {
    const std::size_t N = mesh_.nodeCount(), H = mesh_.hexCount();
    std::vector<std::uint8_t> active(N, 0);
    if (onlyTouched) {
        for (std::size_t v = 0; v < N; ++v)
            if (touched_[v]) markNeighbours(static_cast<Index>(v), active, next);
        std::fill(next.begin(), next.end(), std::uint8_t{0});
    } else {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H, kBlock), [&](const auto& r) {
            for (std::size_t h = r.begin(); h != r.end(); ++h)
                if (!(inverseMeanRatio(hexCoords(mesh_, static_cast<Index>(h))) <= 1.0 + opt_.activeThreshold))
                    for (Index u : mesh_.hexes[h]) raise(active[static_cast<std::size_t>(u)]);
        });
    }
    std::fill(touched_.begin(), touched_.end(), std::uint8_t{0});
    return active;
}

void Smoother::meanRatioPhase(const ObjectiveSum& start, bool onlyTouched) {
    const Stopwatch watch;
    const std::size_t N = mesh_.nodeCount();
    std::vector<std::uint8_t> next(N, 0);
    std::vector<std::uint8_t> active = initialActive(onlyTouched, next);

    double total = 8.0 * start.sum;                        // corner sum, the optimised objective
    const double corners = 8.0 * static_cast<double>(start.finite);
    std::vector<double> gain(N, 0.0);
    // a node's own byte, set at its visit: the visit counts come from it after
    // the sweep, with no counter shared by the threads on the sweep's path
    std::vector<std::uint8_t> visited(N, 0);
    std::vector<std::size_t> visitsPerSweep;  // this phase's, for the progress estimate
    result_.converged = false;

    for (int sweep = 0; sweep < opt_.maxSweeps; ++sweep) {
        std::fill(gain.begin(), gain.end(), 0.0);
        std::fill(next.begin(), next.end(), std::uint8_t{0});
        std::fill(visited.begin(), visited.end(), std::uint8_t{0});
        std::atomic<std::size_t> updates{0};
        sweepColours(colouring_.classes, [&](Index v) {
            const auto sv = static_cast<std::size_t>(v);
            if (!active[sv] || (mode_[sv] == Mode::Curve && !projector_->hasCurves())) return;
            visited[sv] = 1;
            auto& buf = buffers_->local();
            const Visit r = mode_[sv] == Mode::Surface ? surfaceStep(v, buf)
                            : mode_[sv] == Mode::Curve ? curveStep(v, buf)
                                                       : interiorStep(v, buf);
            if (r.move.steps == 0) return;
            moveNode(sv, r.position);
            gain[sv] = r.move.before - r.move.after;
            everMoved_[sv] = 1;
            updates.fetch_add(1, std::memory_order_relaxed);
            if (r.move.displacement.norm() > opt_.wakeTolerance * r.length) markNeighbours(v, active, next);
        });
        active.swap(next);
        double improvement = 0;
        for (double g : gain) improvement += g;
        std::size_t visits = 0, surfaceVisits = 0;
        for (std::size_t v = 0; v < N; ++v)
            if (visited[v]) {
                ++visits;
                surfaceVisits += mode_[v] != Mode::Interior;
            }
        // The running total subtracts the nodes' gains, which count centre
        // frames and corners of hexes that were inverted at the start (not
        // in start.sum), so it drifts low and could go negative after a dozen
        // sweeps, which turned the tolerance off. A corner's inverse mean
        // ratio is at least 1, so the sum is at least `corners`.
        const double before = std::max(total, corners);
        total -= improvement;
        ++result_.sweeps;
        result_.nodeUpdates += updates.load();
        result_.nodeVisits += visits;
        result_.surfaceNodeVisits += surfaceVisits;
        result_.visitHistory.push_back(visits);
        result_.objectiveHistory.push_back(start.finite ? total / corners : 0.0);
        visitsPerSweep.push_back(visits);
        report("mean_ratio", sweepProgress(visitsPerSweep));
        if (!(improvement > opt_.relativeTolerance * before) ||
            std::find(active.begin(), active.end(), std::uint8_t{1}) == active.end()) {
            result_.converged = true;
            break;
        }
    }
    report("mean_ratio", 1.0);
    result_.meanRatioSeconds += watch.seconds();
}

SmoothingResult Smoother::run(bool meanRatio) {
    const Stopwatch watch;
    setUp();
    result_.setupSeconds = watch.seconds();
    report("setup", 1.0);
    {
        const ObjectiveSum s = objectiveNow();
        result_.objectiveBefore = meanOf(s);
        result_.invertedBefore = invertedNow();
    }
    guarded_ = opt_.untangleKeepsValidCorners;
    if (result_.invertedBefore > 0 && opt_.untangle) untanglePhase();
    const ObjectiveSum untangled = objectiveNow();
    result_.objectiveAfterUntangle = meanOf(untangled);
    if (meanRatio && opt_.maxSweeps > 0) meanRatioPhase(untangled);
    else result_.converged = true;
    alternateRounds(meanRatio);
    // Last resort: what is still inverted is usually a fold of the surface
    // mesh itself (two sides of a narrow gap within one cell), which no
    // tangential move can open.
    if (opt_.untangle && opt_.releaseSurfaceToUntangle && projector_ && !opt_.fixBoundary && invertedNow() > 0)
        releasePhase(meanRatio);
    finish();
    result_.seconds = watch.seconds();
    return result_;
}

// The mean-ratio sweeps even out the hexes around what is still inverted,
// which often leaves the untangler room it did not have: alternate while that
// helps.
void Smoother::alternateRounds(bool meanRatio) {
    int stalls = 0;  // rounds in a row that removed no inverted hex
    for (int round = 1; round < opt_.untangleRounds && opt_.untangle; ++round) {
        const std::size_t left = invertedNow();
        if (left == 0) break;
        // Every other round drops the guard that keeps valid corners valid:
        // node by node that guard can lock a tight spot; Knupp's measure
        // summed over the region may still fall by trading one deep inversion
        // for shallow ones that the next guarded round removes. A round that
        // ends with more inverted hexes is undone.
        if (!untangleRound(round % 2 == 1, left)) {
            if (++stalls >= 2) break;
            continue;
        }
        const ObjectiveSum after = objectiveNow();
        if (meanRatio && opt_.maxSweeps > 0) meanRatioPhase(after, true);
        if (invertedNow() < left) stalls = 0;
        else if (++stalls >= 2) break;
    }
}

// Validity comes before fidelity: the surface nodes of the hexes still
// inverted may leave the surface to untangle them; the mean-ratio sweeps then
// pull them back as far as the hexes allow.
void Smoother::releasePhase(bool meanRatio) {
    anchorReleasedNodes();
    releaseSurface_ = true;
    // Guarded first, then (undone if it ends worse) unguarded, each followed
    // by mean-ratio sweeps; pass k lets nodes go k times as far.
    for (int pass = 0; pass < opt_.releasePasses && invertedNow() > 0; ++pass) {
        releaseLimit_ = opt_.releaseDistance * (pass + 1);
        for (const bool guard : {true, false}) {
            const std::size_t left = invertedNow();
            if (left == 0) break;
            untangleRound(guard, left);
        }
        releaseSurface_ = false;
        if (meanRatio && opt_.maxSweeps > 0) meanRatioPhase(objectiveNow(), true);
        releaseSurface_ = true;
    }
    releaseSurface_ = false;
    returnToSurface();
    result_.surfaceNodesReleased =
        static_cast<std::size_t>(std::count(released_.begin(), released_.end(), std::uint8_t{1}));
    anchorNodes_ = {};
    anchor_ = {};
    anchorLength_ = {};
}

// The bound is in edge lengths measured now: with the current length a node
// next to one that went far could go as far again, and so on. Only surface and
// curve nodes can be released, so only they get an anchor (a tenth of the
// nodes on a brain; a copy of every position was 32 bytes per node at peak).
void Smoother::anchorReleasedNodes() {
    released_.assign(mesh_.nodeCount(), 0);
    anchorNodes_.clear();
    for (std::size_t v = 0; v < mesh_.nodeCount(); ++v)
        if (mode_[v] == Mode::Surface || mode_[v] == Mode::Curve) anchorNodes_.push_back(static_cast<Index>(v));
    anchor_.resize(anchorNodes_.size());
    anchorLength_.resize(anchorNodes_.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, anchorNodes_.size(), 1024), [&](const auto& r) {
        auto& buf = buffers_->local();
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const Index v = anchorNodes_[i];
            anchor_[i] = mesh_.nodes[static_cast<std::size_t>(v)];
            const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, v, buf.data());
            anchorLength_[i] = localEdgeLength(buf.data(), n);
        }
    });
}

void Smoother::finish() {
    const ObjectiveSum s = objectiveNow();
    result_.objectiveAfter = meanOf(s);
    result_.invertedAfter = invertedNow();
    const std::vector<std::uint8_t>& inverted = hexInverted_;
    for (std::size_t h = 0; h < inverted.size(); ++h) {
        if (!inverted[h]) continue;
        const HexCoords x = hexCoords(mesh_, static_cast<Index>(h));
        TangledHex t;
        t.hex = static_cast<Index>(h);
        for (const Vec3& p : x)
            for (int i = 0; i < 3; ++i) t.centroid[i] += p[i] / 8.0;
        t.minDeterminant = minJacobianDeterminant(x);
        result_.untangleFailures.push_back(t);
    }
    result_.nodesMoved = static_cast<std::size_t>(std::count(everMoved_.begin(), everMoved_.end(), std::uint8_t{1}));
}

}  // namespace detail

void checkOptions(const SmoothingOptions& o) {
    auto fail = [](const char* name, double value, const char* want) {
        throw Error(std::string("smoothing option ") + name + " is " + std::to_string(value) + "; it must be " + want);
    };
    // Negated comparisons so that NaN fails them too.
    auto atLeast = [&](const char* name, double value, double lo, const char* want) {
        if (!(value >= lo)) fail(name, value, want);
    };
    auto finiteAtLeast = [&](const char* name, double value, double lo, const char* want) {
        if (!(value >= lo && std::isfinite(value))) fail(name, value, want);
    };
    atLeast("maxUntangleSweeps", o.maxUntangleSweeps, 0, "0 or more");
    finiteAtLeast("untangleBeta", o.untangleBeta, 0, "a finite fraction >= 0");
    atLeast("maxUntangleGrowth", o.maxUntangleGrowth, 0, "0 or more");
    atLeast("untanglePolishSweeps", o.untanglePolishSweeps, 0, "0 or more");
    if (!(o.untangleMaxTravel > 0))
        fail("untangleMaxTravel", o.untangleMaxTravel, "a positive number of edge lengths (infinity for no bound)");
    atLeast("untangleRounds", o.untangleRounds, 0, "0 or more");
    finiteAtLeast("releaseDistance", o.releaseDistance, 0, "a finite number of edge lengths >= 0");
    atLeast("releasePasses", o.releasePasses, 0, "0 or more");
    atLeast("maxSweeps", o.maxSweeps, 0, "0 or more");
    finiteAtLeast("relativeTolerance", o.relativeTolerance, 0, "a finite fraction >= 0");
    finiteAtLeast("wakeTolerance", o.wakeTolerance, 0, "a finite fraction >= 0");
    finiteAtLeast("moveTolerance", o.moveTolerance, 0, "a finite fraction >= 0");
    finiteAtLeast("activeThreshold", o.activeThreshold, 0, "a finite number >= 0");
    finiteAtLeast("gradientTolerance", o.gradientTolerance, 0, "a finite number >= 0");
    finiteAtLeast("surfaceRelaxation", o.surfaceRelaxation, 0, "a finite fraction >= 0");
    atLeast("surfaceHalvings", o.surfaceHalvings, 0, "0 or more");
    atLeast("newton.maxIterations", o.newton.maxIterations, 0, "0 or more");
    atLeast("newton.maxHalvings", o.newton.maxHalvings, 0, "0 or more");
    finiteAtLeast("newton.armijo", o.newton.armijo, 0, "a finite fraction >= 0");
    if (!(o.newton.maxStep > 0 && std::isfinite(o.newton.maxStep)))
        fail("newton.maxStep", o.newton.maxStep, "a positive finite number of edge lengths");
    finiteAtLeast("newton.minStep", o.newton.minStep, 0, "a finite number of edge lengths >= 0");
}

SmoothingResult optimizeMesh(HexMesh& mesh, const SurfaceProjector* projector, const SmoothingOptions& options,
                             const Progress& progress, const Topology* topology) {
    checkOptions(options);
    return detail::Smoother(mesh, projector, options, progress, topology).run(true);
}

SmoothingResult untangle(HexMesh& mesh, const SmoothingOptions& options, const Progress& progress) {
    checkOptions(options);
    return detail::Smoother(mesh, nullptr, options, progress, nullptr).run(false);
}

double meanObjective(const HexMesh& mesh, std::size_t* inverted) {
    const detail::ObjectiveSum s = detail::objectiveSum(mesh);
    if (inverted) *inverted = detail::invertedCount(mesh);
    return detail::meanOf(s);
}

}  // namespace isohex::smoothing

// The worst-hex pass: max-min rounds of node moves, release rounds, joint
// moves (JointRelease.cpp), slack rounds, mean rounds and the return of
// surface nodes to their surface, in that order (see WorstHexes.hpp).
#include "isohex/smoothing/WorstHexes.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "NodeHexes.hpp"
#include "WorstHexPass.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/VecMath.hpp"
#include "isohex/smoothing/Colouring.hpp"

namespace isohex::smoothing {

namespace detail {

// One node's search in one round: how the node may move, where it started and
// how a trial position is judged against the best so far.
class NodeSearch {
public:
    NodeSearch(const HexMesh& mesh, const Topology& topo, const WorstHexOptions& opt, Index v, double L)
        : v(v), sv(static_cast<std::size_t>(v)), L(L), nh(mesh, topo, v), opt_(opt) {}

    Index v;
    std::size_t sv;
    bool surface = false, curve = false, release = false, mean = false;
    bool offSurface = false;  // a surface, curve or junction node free in 3-D within surfaceSlack of its places
    bool onSurface = false;   // a surface node that stays on its surface
    bool ascend = false;      // steps along the gradient instead of the compass
    double L;                 // mean edge length at the node
    NodeHexes nh;
    std::vector<double> floors;  // the mean rounds' floors, per hex of nh
    int refusedBy = -1;          // the hex that refused the last trial (aroundUnless)
    Around best;                 // the node's hexes where it is now
    double edgeFloor = 0;        // no edge at the node may end shorter
    double step = 0;
    int maxMoves = 0, moves = 0;

    Around evaluate(const Vec3& p) const { return around(nh, p, opt_.target, mean ? floors.data() : nullptr); }
    Around evaluateTrial(const Vec3& p, const Around& bar) {
        return aroundUnless(nh, p, opt_.target, mean ? floors.data() : nullptr, bar, refusedBy);
    }
    bool improves(const Around& trial, const Around& current) const {
        if (!mean) return better(trial, current);
        return trial.inverted == 0 && trial.sum > current.sum + 1e-12 * static_cast<double>(floors.size());
    }
    bool edgesOk(const Vec3& p) const { return !(opt_.minEdge > 0) || nh.shortestEdge(p) >= edgeFloor; }

private:
    const WorstHexOptions& opt_;
};

WorstHexPass::WorstHexPass(HexMesh& mesh, const SurfaceProjector* projector, const WorstHexOptions& opt,
                           const Topology* topology, const Progress& progress)
    : mesh_(mesh),
      projector_(projector),
      opt_(opt),
      givenTopology_(topology),
      progress_(progress),
      N_(mesh.nodeCount()) {}

// The pass's parts and their shares of its time on ch2bet (bench/RESULTS.md,
// "The optimiser's work"): the max-min rounds 30%, the release, joint and
// slack rounds 10%, the mean rounds 55%, the return the rest.
void WorstHexPass::report(double from, double to, double fraction) const {
    if (progress_) progress_("worst_hexes", from + (to - from) * std::clamp(fraction, 0.0, 1.0));
}

WorstHexResult WorstHexPass::run() {
    if (!measureStart()) return res_;
    prepare();
    // Rounds over the nodes of the hexes below the target until nothing
    // moves; then, if hexes are still inverted, rounds over theirs only,
    // where surface nodes may leave their surface (validity before fidelity:
    // a fold of the surface within one element cannot be opened along it).
    roundsUntilStill({}, 0.0, 0.3);
    if (projector_ != nullptr && opt_.releaseDistance > 0 &&
        std::any_of(sj_.begin(), sj_.end(), [](double s) { return !(s > 0); }))
        roundsUntilStill({.release = true}, 0.3, 0.33);
    if (projector_ != nullptr && opt_.releaseDistance > 0 && opt_.jointRings > 0) jointMoves();
    report(0.33, 0.35, 1.0);
    // Then the max-min rounds again with surface nodes free in 3-D within
    // surfaceSlack of their surface: on a fold or spur finer than an element
    // the hexes under a surface quad can open only across the surface. After
    // the release and the joint moves, so that what they do with inverted
    // hexes does not depend on the slack (with the slack first, one mesh kept
    // 2 inverted hexes the joint release had cleared). The return runs before
    // them: they raise hexes and with them the floors, which would keep nodes
    // released to untangle farther off.
    if (projector_ != nullptr && opt_.surfaceSlack > 0) {
        returnToSurface(false);
        roundsUntilStill({.slack = true}, 0.35, 0.4);
    }
    if (meanRounds_) meanRestore();
    report(0.4, 0.95, 1.0);
    returnToSurface(true);
    finish();
    report(0.95, 1.0, 1.0);
    return res_;
}

bool WorstHexPass::measureStart() {
    if (mesh_.hexCount() == 0) return false;
    sj_ = scaledJacobians(mesh_);
    for (double& s : sj_)
        if (scaledJacobianCollapsed(s)) s = -2.0;
    res_.minBefore = sj_.empty() ? 0.0 : *std::min_element(sj_.begin(), sj_.end());
    res_.belowBefore = countBelow(opt_.target);
    res_.reportedBelowBefore = opt_.reportBelow > 0 ? countBelow(opt_.reportBelow) : 0;
    res_.minAfter = res_.minBefore;
    res_.belowAfter = res_.belowBefore;
    res_.reportedBelowAfter = res_.reportedBelowBefore;
    meanRounds_ =
        opt_.meanRounds > 0 && std::any_of(sj_.begin(), sj_.end(), [&](double s) { return s < opt_.meanBelow; });
    return res_.belowBefore > 0 || meanRounds_ || (projector_ != nullptr && opt_.returnPasses > 0);
}

void WorstHexPass::prepare() {
    // The pass reads the node-to-hex rows, the boundary flags and the
    // boundary and interface quads (normals, junctions), never the edges.
    if (!givenTopology_) ownTopology_ = buildTopology(mesh_, TopologyParts::Surfaces);
    else requireTopologyOf(mesh_, *givenTopology_, "worst-hex pass");
    topo_ = givenTopology_ ? givenTopology_ : &ownTopology_;
    everMoved_.assign(N_, 0);
    released_.assign(N_, 0);
    settled_.assign(N_, 0);
    for (int i = 0; i < 3; ++i)
        for (int s = -1; s <= 1; s += 2) {
            Vec3 d{0, 0, 0};
            d[static_cast<std::size_t>(i)] = s;
            dirs3_.push_back(d);
        }
    for (int a = -1; a <= 1; a += 2)
        for (int b = -1; b <= 1; b += 2)
            for (int c = -1; c <= 1; c += 2)
                dirs3_.push_back((1.0 / std::sqrt(3.0)) * Vec3{double(a), double(b), double(c)});
    normal_ = surfaceNormals(mesh_, *topo_);
    if (projector_ != nullptr && opt_.surfaceSlack > 0) findJunctions();
}

// Junction nodes next to a surface the projector does not find stay fixed
// (no distance to it can be measured).
void WorstHexPass::findJunctions() {
    junctions_ = junctionSurfaces(mesh_, *topo_);
    for (std::vector<std::int32_t>& ids : junctions_.surfaces)
        if (std::any_of(ids.begin(), ids.end(), [&](std::int32_t id) { return !projector_->projectsOnto(id); })) ids.clear();
}

void WorstHexPass::roundsUntilStill(RoundKind kind, double from, double to) {
    for (int round = 0; round < opt_.maxRounds && runRound(kind); ++round)
        report(from, to, static_cast<double>(round + 1) / opt_.maxRounds);
    report(from, to, 1.0);
}

// Last, rounds that raise the mean: the max-min rounds stop once every hex is
// at the target, and the optimiser's inverse mean ratio is not the scaled
// Jacobian, so most sheet hexes have room left.
void WorstHexPass::meanRestore() {
    const Stopwatch watch;
    double before = 0;
    for (double v : sj_) before += v;
    // The mean rounds trade a hex above the target for the sum; they never
    // take one below the worst hex they start from (a mesh whose worst hex is
    // above the target keeps it: the torus phantom lost 0.011 of it).
    meanFloor_ = std::max(opt_.target, sj_.empty() ? 0.0 : *std::min_element(sj_.begin(), sj_.end()));
    if (opt_.meanOnlyNearMoved) markNearMoved();
    for (int round = 0; round < opt_.meanRounds && runRound({.mean = true}); ++round) {
        ++res_.meanRounds;
        report(0.4, 0.95, static_cast<double>(round + 1) / opt_.meanRounds);
    }
    double after = 0;
    for (double v : sj_) after += v;
    res_.meanGain = sj_.empty() ? 0.0 : (after - before) / static_cast<double>(sj_.size());
    res_.meanSeconds = watch.seconds();
}

void WorstHexPass::finish() {
    res_.minAfter = *std::min_element(sj_.begin(), sj_.end());
    res_.belowAfter = countBelow(opt_.target);
    res_.reportedBelowAfter = opt_.reportBelow > 0 ? countBelow(opt_.reportBelow) : 0;
    res_.nodesMoved = static_cast<std::size_t>(std::count(everMoved_.begin(), everMoved_.end(), 1));
    if (opt_.listMovedNodes)
        for (std::size_t v = 0; v < everMoved_.size(); ++v)
            if (everMoved_[v]) res_.movedNodes.push_back(static_cast<Index>(v));
    res_.surfaceNodesReleased = static_cast<std::size_t>(std::count(released_.begin(), released_.end(), 1));
}

bool WorstHexPass::movable(Index v) const {
    const NodeClass& c = mesh_.nodeClass[static_cast<std::size_t>(v)];
    // (Interior-classified nodes on the boundary, Fixed nodes and Curve
    // nodes where the projector knows no curve never move.)
    if (c.kind == NodeKind::Interior) return !topo_->nodeOnBoundary[static_cast<std::size_t>(v)];
    if (c.kind == NodeKind::Curve) return projector_ != nullptr && projector_->hasCurves() && c.id >= 0;
    return c.kind == NodeKind::Surface && projector_ != nullptr;
}

bool WorstHexPass::freeInSlack(std::size_t v) const {
    const NodeClass& c = mesh_.nodeClass[v];
    if (c.kind == NodeKind::Surface) return projector_->projectsOnto(c.id);
    if (c.kind != NodeKind::Curve) return false;
    if (c.id >= 0) return projector_->hasCurves();
    const std::vector<std::int32_t>* ids = junctions_.of(static_cast<Index>(v));
    return ids != nullptr && !ids->empty();
}

bool WorstHexPass::withinBounds(Index v, const Vec3& p, const std::vector<double>& bounds) const {
    const std::vector<double> d = distancesFromPlace(mesh_, *projector_, junctions_, v, p);
    if (d.size() != bounds.size()) return false;
    for (std::size_t i = 0; i < d.size(); ++i)
        if (!(d[i] <= bounds[i])) return false;  // (a NaN distance is refused)
    return true;
}

// (NaN where the projection fails, so that a bound `!(offBy(..) <= b)` refuses it.)
double WorstHexPass::offBy(std::size_t v, const Vec3& p) const {
    return distanceFromPlace(mesh_, *projector_, junctions_, static_cast<Index>(v), p);
}

// Its value now, or the target (once the mean rounds start, the worst hex then if higher) if it is above that; a valid hex stays valid
// even with a target of 0.
std::vector<double> WorstHexPass::floorsOf(const NodeHexes& nh) const {
    std::vector<double> floors(nh.size());
    for (std::size_t k = 0; k < nh.size(); ++k) {
        const double s0 = sj_[static_cast<std::size_t>(nh.hex(k))];
        floors[k] = s0 > 0 ? std::max(std::min(s0, std::max(opt_.target, meanFloor_)), std::numeric_limits<double>::min()) : s0;
    }
    return floors;
}

void WorstHexPass::refreshAround(std::size_t v) {
    for (const Index* h = topo_->nodeHexes.begin(v); h != topo_->nodeHexes.end(v); ++h)
        sj_[static_cast<std::size_t>(*h)] = usableScaledJacobian(hexCoords(mesh_, *h));
}

void WorstHexPass::markNearMoved() {
    nearMoved_.assign(N_, 0);
    for (std::size_t v = 0; v < N_; ++v) {
        if (!everMoved_[v]) continue;
        for (const Index* h = topo_->nodeHexes.begin(v); h != topo_->nodeHexes.end(v); ++h)
            for (Index u : mesh_.hexes[static_cast<std::size_t>(*h)]) nearMoved_[static_cast<std::size_t>(u)] = 1;
    }
}

std::size_t WorstHexPass::countBelow(double threshold) const {
    return static_cast<std::size_t>(std::count_if(sj_.begin(), sj_.end(), [&](double s) { return s < threshold; }));
}

// A node is picked when one of its hexes is below the round's threshold (for
// the release rounds, not valid), it may move in the round, and (in the mean
// rounds with meanOnlyNearMoved) it is near a moved node. The max-min and
// slack rounds work on a few hexes: their nodes are found from those hexes.
// Where many hexes are below (the mean rounds pick about 580 k nodes of a 2 M-
// node mesh) the nodes are picked one by one in parallel (a serial pass over
// the hexes with a sort took 0.16 s a round there). Both give the same picks.
std::vector<std::uint8_t> WorstHexPass::pickNodes(RoundKind kind) const {
    const double below = kind.mean ? opt_.meanBelow : opt_.target;
    auto hexIn = [&](double s) { return kind.release ? !(s > 0) : s < below; };
    auto pickable = [&](std::size_t v) {
        const bool near = !kind.mean || nearMoved_.empty() || nearMoved_[v];
        return near && (movable(static_cast<Index>(v)) || (kind.slack && freeInSlack(v)));
    };
    std::vector<std::uint8_t> pick(N_, 0);
    std::vector<Index> few;
    const std::size_t most = N_ / 64;
    for (std::size_t h = 0; h < sj_.size() && few.size() <= most; ++h)
        if (hexIn(sj_[h])) few.push_back(static_cast<Index>(h));
    if (few.size() <= most) {
        for (Index h : few)
            for (Index u : mesh_.hexes[static_cast<std::size_t>(h)]) {
                const auto su = static_cast<std::size_t>(u);
                if (!pick[su] && pickable(su)) pick[su] = 1;
            }
        return pick;
    }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, N_, 4096), [&](const auto& r) {
        for (std::size_t v = r.begin(); v != r.end(); ++v) {
            bool in = false;
            for (const Index* h = topo_->nodeHexes.begin(v); h != topo_->nodeHexes.end(v) && !in; ++h)
                in = hexIn(sj_[static_cast<std::size_t>(*h)]);
            pick[v] = in && pickable(v);
        }
    });
    return pick;
}

// Nodes sharing no hex move at once: one colour class per parallel loop,
// classes in order, so the result is the same for any number of threads.
bool WorstHexPass::runRound(RoundKind kind) {
    const std::vector<std::uint8_t> pick = pickNodes(kind);
    if (std::find(pick.begin(), pick.end(), std::uint8_t{1}) == pick.end()) return false;
    if (kind.id() != settledKind_) {
        std::fill(settled_.begin(), settled_.end(), std::uint8_t{0});
        settledKind_ = kind.id();
    }
    const NodeColouring colouring = colourNodes(mesh_, topo_->nodeHexes, pick);
    std::atomic<bool> anyMove{false};
    for (const std::vector<Index>& cls : colouring.classes)
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, cls.size(), 16), [&](const auto& range) {
            for (std::size_t i = range.begin(); i != range.end(); ++i)
                if (!settled_[static_cast<std::size_t>(cls[i])] && visit(cls[i], kind)) anyMove = true;
        });
    ++res_.rounds;
    return anyMove.load();
}

// With `release`, a surface node moves in 3-D, off its surface, but stays
// within releaseDistance local edge lengths of it. With `mean` (the mean
// rounds), a trial is better when it raises the summed scaled Jacobian of the
// node's hexes and leaves none of them below its floor: its value at the
// start of the visit, or the target if it was above that.
bool WorstHexPass::visit(Index v, RoundKind kind) {
    const auto sv = static_cast<std::size_t>(v);
    const bool surface = mesh_.nodeClass[sv].kind == NodeKind::Surface;
    const bool curve = mesh_.nodeClass[sv].kind == NodeKind::Curve;
    if (curve && kind.release) return false;  // curve nodes stay on their curve
    // In the slack rounds a surface or curve node moves in 3-D, off its
    // surface or curve by at most surfaceSlack (not off a surface the
    // projector leaves alone); a junction node stays within surfaceSlack of
    // every surface around it.
    const bool offSurface = kind.slack && freeInSlack(sv);
    const bool onSurface = surface && !kind.release && !offSurface;
    // The mean rounds step along the gradient of the summed scaled Jacobian
    // of the node's hexes (in its tangent plane on a surface), halving the
    // step until a position is better; a curve node keeps the compass search
    // along its curve.
    const bool ascend = kind.mean && !curve;
    if (onSurface && !(norm(normal_[sv]) > 0)) return false;
    const std::vector<Vec3> dirs = compassDirections(sv, onSurface && !ascend, kind.mean && !onSurface);
    const double L = meanEdgeLengthAt(mesh_, *topo_, v);
    if (!(L > 0)) return false;
    NodeSearch s(mesh_, *topo_, opt_, v, L);
    s.surface = surface;
    s.curve = curve && !offSurface;
    s.release = kind.release;
    s.mean = kind.mean;
    s.offSurface = offSurface;
    s.onSurface = onSurface;
    s.ascend = ascend;
    if (kind.mean) s.floors = floorsOf(s.nh);
    s.best = s.evaluate(mesh_.nodes[sv]);
    // No edge at the node may end shorter than minEdge x L, or than it was
    // if it was shorter (see WorstHexOptions::minEdge).
    s.edgeFloor = std::min(s.nh.shortestEdge(mesh_.nodes[sv]), opt_.minEdge * L);
    s.step = (kind.mean ? opt_.meanFirstStep : opt_.firstStep) * L;
    // Off the surface by at most surfaceSlack: longer steps cannot pass.
    if (offSurface) s.step = std::min(s.step, opt_.surfaceSlack);
    s.maxMoves = kind.mean ? opt_.meanMovesPerVisit : opt_.maxMovesPerVisit;
    if (ascend) ascendSteps(s);
    else compassSteps(s, dirs);
    if (!s.moves) {
        settled_[sv] = 1;
        return false;
    }
    everMoved_[sv] = 1;
    if (surface && kind.release) released_[sv] = 1;
    refreshAround(sv);
    clearAround(mesh_, topo_->nodeHexes, v, settled_);  // nodes sharing a hex with it may move now
    return true;
}

// In 3-D, the 6 axes and 8 cube diagonals; in a tangent plane (`tangent`), 8
// directions 45 degrees apart. `axesOnly`: a curve node in the mean rounds
// tries the 6 axes only, onto its curve (with the diagonals as well the
// rounds took 70% more time for 6% more gain).
std::vector<Vec3> WorstHexPass::compassDirections(std::size_t sv, bool tangent, bool axesOnly) const {
    std::vector<Vec3> dirs = dirs3_;
    if (tangent) {
        const Vec3 n = normal_[sv];
        const Vec3 helper = std::abs(n[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
        Vec3 t1 = cross(n, helper);
        t1 = (1.0 / norm(t1)) * t1;
        const Vec3 t2 = cross(n, t1);
        dirs.clear();
        for (int k = 0; k < 8; ++k) {
            const double a = k * M_PI / 4.0;
            dirs.push_back(std::cos(a) * t1 + std::sin(a) * t2);
        }
    }
    if (axesOnly) dirs.resize(6);
    return dirs;
}

// Along the gradient of the summed scaled Jacobian (in the tangent plane on a
// surface, then projected), halving the step until a position is better.
void WorstHexPass::ascendSteps(NodeSearch& s) {
    const std::size_t sv = s.sv;
    while (s.step >= opt_.lastStep * s.L && s.moves < s.maxMoves) {
        Vec3 g = s.nh.summedGradient(mesh_.nodes[sv]);
        if (s.onSurface) {
            const Vec3 nu = (1.0 / norm(normal_[sv])) * normal_[sv];
            g = g - dot(g, nu) * nu;
        }
        const double gn = norm(g);
        if (!(gn > 0) || !std::isfinite(gn)) break;
        const Vec3 d = (1.0 / gn) * g;
        bool moved = false;
        for (; s.step >= opt_.lastStep * s.L; s.step *= 0.5) {
            Vec3 p = mesh_.nodes[sv] + s.step * d;
            if (s.onSurface) p = projector_->project(mesh_.nodeClass[sv].id, p);
            if (!finite(p)) continue;
            // The hexes first: most trials fail there, after a hex or two
            // (see compassSteps).
            const Around f = s.evaluateTrial(p, s.best);
            if (s.improves(f, s.best) && s.edgesOk(p)) {
                mesh_.nodes[sv] = p;
                s.best = f;
                ++s.moves;
                moved = true;
                break;
            }
        }
        if (!moved) break;
    }
}

void WorstHexPass::compassSteps(NodeSearch& s, const std::vector<Vec3>& dirs) {
    const std::size_t sv = s.sv;
    // A node that starts the visit farther off its surface, curve or one of
    // its junction surfaces than the round allows (a vertex contouring held
    // back; a junction node, which no point puts on all its surfaces) may
    // still move, as long as it gets no farther off each than it was: else
    // it could never move at all.
    const double offAtStart = s.surface && s.release ? offBy(sv, mesh_.nodes[sv]) : 0.0;
    const double releaseBound = std::max(opt_.releaseDistance * s.L, offAtStart);
    std::vector<double> slackBounds;
    if (s.offSurface) {
        slackBounds = distancesFromPlace(mesh_, *projector_, junctions_, s.v, mesh_.nodes[sv]);
        for (double& b : slackBounds) b = std::max(opt_.surfaceSlack, b);  // (a NaN start: the slack)
    }
    while (s.step >= opt_.lastStep * s.L && s.moves < s.maxMoves) {
        Vec3 bestPos = mesh_.nodes[sv];
        Around bestValue = s.best;
        for (const Vec3& d : dirs) {
            Vec3 p = mesh_.nodes[sv] + s.step * d;
            if (s.onSurface) p = projector_->project(mesh_.nodeClass[sv].id, p);
            // a curve node: the 3-D trial point onto its curve (both ways along it)
            if (s.curve) p = projector_->projectToCurve(mesh_.nodeClass[sv].id, p);
            if (!finite(p)) continue;
            // Whether the hexes get better is asked first: most trials fail
            // there, often after one hex (evaluateTrial stops at the first
            // hex that refuses them), which costs less than the shortest edge
            // and far less than a projection for the surface bounds. The
            // tests have no side effects on the outcome (evaluateTrial's
            // remembered hex only orders its own work), so the search takes
            // the same path as with the bounds first.
            const Around f = s.evaluateTrial(p, bestValue);
            if (!s.improves(f, bestValue)) continue;
            if (s.surface && s.release && !(offBy(sv, p) <= releaseBound)) continue;
            if (s.offSurface && !withinBounds(s.v, p, slackBounds)) continue;
            if (!s.edgesOk(p)) continue;
            bestValue = f;
            bestPos = p;
        }
        if (s.improves(bestValue, s.best)) {
            mesh_.nodes[sv] = bestPos;
            s.best = bestValue;
            ++s.moves;
        } else {
            s.step *= 0.5;
        }
    }
}

// The return: surface nodes still off their surface (released here or by the
// optimiser) go back towards it as far as the hexes around them allow: the
// largest of 1, 1/2, ... 1/64 of the way to their projection that leaves no
// hex around them below the smaller of its value and the target, so the
// minimum cannot fall. One node at a time in index order (few nodes; the same
// result for any thread count), repeated while a node gets closer, since one
// node's return can make room for the next.
void WorstHexPass::returnToSurface(bool last) {
    if (projector_ == nullptr || opt_.returnPasses <= 0) return;
    const Stopwatch watch;
    std::vector<double> off(N_, 0.0);
    std::vector<Index> candidates = offSurfaceNodes(off);
    if (last) res_.surfaceNodesOffBefore = candidates.size();
    for (int pass = 0; pass < opt_.returnPasses && !candidates.empty(); ++pass) {
        const bool closer = returnPass(candidates);
        candidates = stillOff(candidates, off);
        if (!closer) break;
    }
    // What stays off is marked and counted by the last call only: the rounds
    // in between may still move a node onto its surface (an extraction corner
    // held back, say, which no round released).
    if (last) countLeftOff(candidates, off);
    res_.returnSeconds += watch.seconds();
}

double WorstHexPass::distanceOff(std::size_t v) const {
    const double d = offBy(v, mesh_.nodes[v]);
    return std::isfinite(d) ? d : 0.0;
}

std::vector<Index> WorstHexPass::offSurfaceNodes(std::vector<double>& off) const {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, N_, 1024), [&](const auto& r) {
        for (std::size_t v = r.begin(); v != r.end(); ++v)
            if (mesh_.nodeClass[v].kind == NodeKind::Surface && movable(static_cast<Index>(v))) off[v] = distanceOff(v);
    });
    std::vector<Index> candidates;
    for (std::size_t v = 0; v < N_; ++v) {
        if (!(off[v] > 0)) continue;
        const double L = meanEdgeLengthAt(mesh_, *topo_, static_cast<Index>(v));
        if (off[v] > opt_.returnTolerance * L) candidates.push_back(static_cast<Index>(v));
    }
    return candidates;
}

bool WorstHexPass::returnPass(const std::vector<Index>& candidates) {
    bool closer = false;
    for (Index v : candidates) {
        const auto sv = static_cast<std::size_t>(v);
        const Vec3 x = mesh_.nodes[sv];
        const Vec3 q = projector_->project(mesh_.nodeClass[sv].id, x);
        if (!finite(q)) continue;
        const NodeHexes nh(mesh_, *topo_, v);
        const std::vector<double> floors = floorsOf(nh);
        double t = 1;
        for (int k = 0; k <= 6; ++k, t *= 0.5) {
            const Vec3 p = k == 0 ? q : x + t * (q - x);
            if (around(nh, p, opt_.target, floors.data()).inverted == 0) {
                mesh_.nodes[sv] = p;
                everMoved_[sv] = 1;
                closer = true;
                refreshAround(sv);
                break;
            }
        }
    }
    return closer;
}

std::vector<Index> WorstHexPass::stillOff(const std::vector<Index>& candidates, std::vector<double>& off) {
    std::vector<Index> still;
    for (Index v : candidates) {
        const auto sv = static_cast<std::size_t>(v);
        off[sv] = distanceOff(sv);
        if (off[sv] > opt_.returnTolerance * meanEdgeLengthAt(mesh_, *topo_, v)) still.push_back(v);
        else released_[sv] = 0;
    }
    return still;
}

// Off by no more than the slack is within the tolerance the caller set:
// counted apart, not as released.
void WorstHexPass::countLeftOff(const std::vector<Index>& candidates, const std::vector<double>& off) {
    std::size_t withinSlack = 0;
    for (Index v : candidates) {
        const auto sv = static_cast<std::size_t>(v);
        const bool within = opt_.surfaceSlack > 0 && off[sv] <= opt_.surfaceSlack;  // (measured by stillOff)
        released_[sv] = within ? 0 : 1;
        withinSlack += within;
    }
    res_.surfaceNodesWithinSlack = withinSlack;
    res_.surfaceNodesOffAfter = candidates.size() - withinSlack;
}

}  // namespace detail

WorstHexResult raiseWorstHexes(HexMesh& mesh, const SurfaceProjector* projector, const WorstHexOptions& opt,
                               const Topology* topology, const Progress& progress) {
    return detail::WorstHexPass(mesh, projector, opt, topology, progress).run();
}

}  // namespace isohex::smoothing

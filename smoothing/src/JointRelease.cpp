// Joint release: all movable nodes within a few rings of an inverted hex move
// together.
//
// The compass search moves one node at a time and never accepts a move that
// leaves more hexes inverted around that node. Where a pit or pocket of the
// isosurface is much smaller than an element (a pocket of about one voxel
// under a one-cell pit of the dual-contouring surface), the pillow hexes of
// the pit's floor and walls are coupled: lifting one above zero tips the next
// below, so node by node they stall just below zero. Moving the nodes of two
// rings jointly (surface nodes off the surface by at most releaseDistance
// edge lengths, as in the release rounds) finds valid configurations there:
// with the surface nodes held within 0.1 voxel none was found, with 1 voxel
// the whole region rose above 0.3.
//
// Method: gradient ascent (Adam-style scaling per coordinate) on a soft
// minimum (log-sum-exp) of every scaled-Jacobian frame of the hexes touching
// a free node, with the softness lowered in stages; surface nodes are put
// back within their bound after each step. The best iterate is kept only if
// it beats the start on (inverted hexes, smallest scaled Jacobian) over
// those hexes, so nothing gets worse and no hex outside the region changes.
// The result does not depend on the thread count.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "HexFrames.hpp"
#include "NodeHexes.hpp"
#include "WorstHexPass.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex::smoothing::detail {

namespace {

struct RegionScore {
    int inverted = 0;
    double min = std::numeric_limits<double>::infinity();
};

RegionScore scoreHexes(const HexMesh& mesh, const std::vector<Index>& hexes) {
    RegionScore r;
    for (Index h : hexes) {
        const double s = usableScaledJacobian(hexCoords(mesh, h));
        r.inverted += !(s > 0);
        r.min = std::min(r.min, s);
    }
    return r;
}

bool betterRegion(const RegionScore& a, const RegionScore& b) {
    if (a.inverted != b.inverted) return a.inverted < b.inverted;
    return a.min > b.min + 1e-12;
}

// One joint move of a region: the soft-min ascent over its free nodes. It
// reads and writes only the region's free nodes and reads the nodes of its
// hexes.
class JointMove {
public:
    JointMove(HexMesh& mesh, const Topology& topo, const SurfaceProjector& projector, const WorstHexOptions& opt,
              const Region& region)
        : mesh_(mesh), topo_(topo), projector_(projector), opt_(opt), free_(region.free), hexes_(region.hexes),
          F_(free_.size()), H_(hexes_.size()) {}

    // Local numbering of the free nodes, their bounds and starting points;
    // false if there is nothing to move.
    bool setUp();
    // The ascent in four stages of softness, `iterations` steps each; true
    // with the nodes at the best iterate if that beats the start, else false
    // with the nodes back at their start.
    bool ascend(int iterations, bool byVolume);
    // Surface nodes back towards the surface: the largest of 1, 1/2, ... 1/64
    // of the way that keeps the hexes around them at least half as good as
    // the joint move left them (never inverted).
    void settleSurfaceNodes();

    std::size_t size() const { return F_; }
    const Vec3& start(std::size_t i) const { return start_[i]; }
    bool isSurface(std::size_t i) const { return isSurface_[i] != 0; }
    double length() const { return L_; }

private:
    // One step: soft-min weights over all frames of the region's hexes (the
    // gradient of -tau log sum exp(-s/tau) is the weighted sum of the frames'
    // gradients, weights exp(-s/tau) normalised), the nodes' gradients, an
    // Adam move, and the best iterate kept.
    void step(double tau);
    // The frames of every hex; the smallest frame value of the region.
    double formFrames();
    // The unnormalised soft-min weights of every frame; their total.
    double softMinWeights(double tau, double lowest);
    // The weights normalised, each hex's node gradients, summed per free node
    // in the serial order.
    void nodeGradients(double total);
    // Adam-scaled move of every free node, surface nodes put back within their bound.
    void adamMove();
    // The region scored now; the positions kept if better than the best so far.
    void keepIfBest();
    // Surface node i at p: back within its bound of the surface (its
    // projection), or to `fallback` if the projection fails.
    void constrain(std::size_t i, Vec3& p, const Vec3& fallback) const;
    // The per-hex work of a step runs in parallel; what adds up across hexes
    // (the weights' total, the gradient of a node shared by several hexes) is
    // summed afterwards in the serial order, and minima and counts do not
    // depend on order, so the steps are the serial ones to the last bit for
    // any thread count.
    template <class Body>
    void forHexes(Body&& body) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H_, kGrain), [&](const auto& r) {
            for (std::size_t k = r.begin(); k != r.end(); ++k) body(k);
        });
    }
    static constexpr std::size_t kGrain = 16;

    HexMesh& mesh_;
    const Topology& topo_;
    const SurfaceProjector& projector_;
    const WorstHexOptions& opt_;
    const std::vector<Index>& free_;
    const std::vector<Index>& hexes_;
    const std::size_t F_, H_;
    // per free node
    std::vector<Vec3> start_, bestAt_, m1_, m2_, grad_;
    std::vector<double> bound_;
    std::vector<std::uint8_t> isSurface_, pinned_;  // pinned: kept in free_ for the numbering, never moved
    // per hex
    std::vector<std::array<std::ptrdiff_t, 8>> localNodes_;  // its nodes in the local numbering (-1: not free)
    std::vector<double> w_, hexLowest_, hexScore_;
    std::vector<HexFrames> frames_;
    std::vector<std::array<Vec3, 8>> hexGrad_;
    double L_ = 0, lr_ = 0, scale_ = 0;
    RegionScore best_;
};

bool JointMove::setUp() {
    start_.resize(F_);
    bound_.assign(F_, 0.0);
    isSurface_.assign(F_, 0);
    for (std::size_t i = 0; i < F_; ++i) {
        const auto sv = static_cast<std::size_t>(free_[i]);
        start_[i] = mesh_.nodes[sv];
        const double l = meanEdgeLengthAt(mesh_, topo_, free_[i]);
        L_ += l / static_cast<double>(F_);
        if (mesh_.nodeClass[sv].kind == NodeKind::Surface) {
            isSurface_[i] = 1;
            // A node the optimiser's own release left farther off may stay
            // as far off, but not go farther; one whose projection fails
            // already (more than a few voxels off) stays put.
            const Vec3 q = projector_.project(mesh_.nodeClass[sv].id, start_[i]);
            const bool ok = finite(q);
            bound_[i] = ok ? std::max(opt_.releaseDistance * l, norm(q - start_[i])) : -1;
        }
    }
    pinned_.assign(F_, 0);
    for (std::size_t i = 0; i < F_; ++i) pinned_[i] = isSurface_[i] && bound_[i] < 0;
    if (!(L_ > 0)) return false;
    auto local = [&](Index v) {
        const auto it = std::lower_bound(free_.begin(), free_.end(), v);
        return it != free_.end() && *it == v ? static_cast<std::ptrdiff_t>(it - free_.begin()) : std::ptrdiff_t{-1};
    };
    localNodes_.resize(H_);
    for (std::size_t k = 0; k < H_; ++k)
        for (std::size_t n = 0; n < 8; ++n) localNodes_[k][n] = local(mesh_.hexes[static_cast<std::size_t>(hexes_[k])][n]);
    return true;
}

bool JointMove::ascend(int iterations, bool byVolume) {
    const RegionScore before = scoreHexes(mesh_, hexes_);
    best_ = before;
    bestAt_ = start_;
    m1_.assign(F_, Vec3{0, 0, 0});
    m2_.assign(F_, Vec3{0, 0, 0});
    grad_.resize(F_);
    w_.resize(9 * H_);
    hexLowest_.resize(H_);
    hexScore_.resize(H_);
    frames_.resize(H_);
    hexGrad_.resize(H_);
    lr_ = opt_.jointStep * L_;
    scale_ = byVolume ? 1.0 / (L_ * L_ * L_) : 0.0;
    for (const double tau : {0.05, 0.02, 0.01, 0.005}) {
        for (int it = 0; it < iterations; ++it) step(tau);
        lr_ *= 0.5;
        // Nothing left for this pass to aim at in the region: stop early.
        if (best_.inverted == 0 && best_.min >= opt_.target) break;
    }
    if (!betterRegion(best_, before)) {
        for (std::size_t i = 0; i < F_; ++i) mesh_.nodes[static_cast<std::size_t>(free_[i])] = start_[i];
        return false;
    }
    for (std::size_t i = 0; i < F_; ++i) mesh_.nodes[static_cast<std::size_t>(free_[i])] = bestAt_[i];
    return true;
}

void JointMove::step(double tau) {
    const double lowest = formFrames();
    const double total = softMinWeights(tau, lowest);
    nodeGradients(total);
    adamMove();
    keepIfBest();
}

double JointMove::formFrames() {
    forHexes([&](std::size_t k) {
        frameValues(hexCoords(mesh_, hexes_[k]), frames_[k], scale_);
        double m = std::numeric_limits<double>::infinity();
        for (const FrameState& st : frames_[k]) m = std::min(m, st.s);
        hexLowest_[k] = m;
    });
    double lowest = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < H_; ++k) lowest = std::min(lowest, hexLowest_[k]);
    return lowest;
}

double JointMove::softMinWeights(double tau, double lowest) {
    forHexes([&](std::size_t k) {
        for (std::size_t f = 0; f < 9; ++f) {
            // exp(-x) < 1e-12 for x > 27.7 (-ln 1e-12 = 27.63): weight 0
            // either way, without the exp.
            const double x = (frames_[k][f].s - lowest) / tau;
            const double e = x > 27.7 ? 0.0 : std::exp(-x);
            w_[9 * k + f] = e > 1e-12 ? e : 0.0;
        }
    });
    double total = 0;
    for (std::size_t k = 0; k < 9 * H_; ++k) total += w_[k];
    return total;
}

void JointMove::nodeGradients(double total) {
    forHexes([&](std::size_t k) {
        for (std::size_t f = 0; f < 9; ++f) w_[9 * k + f] /= total;
        hexGrad_[k].fill(Vec3{0, 0, 0});
        frameGradients(frames_[k], &w_[9 * k], hexGrad_[k], scale_);
    });
    std::fill(grad_.begin(), grad_.end(), Vec3{0, 0, 0});
    for (std::size_t k = 0; k < H_; ++k)
        for (std::size_t n = 0; n < 8; ++n) {
            const std::ptrdiff_t i = localNodes_[k][n];
            if (i >= 0) grad_[static_cast<std::size_t>(i)] = grad_[static_cast<std::size_t>(i)] + hexGrad_[k][n];
        }
}

void JointMove::adamMove() {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, F_, kGrain), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            if (pinned_[i]) continue;
            Vec3& x = mesh_.nodes[static_cast<std::size_t>(free_[i])];
            const Vec3 old = x;
            for (std::size_t c = 0; c < 3; ++c) {
                m1_[i][c] = 0.9 * m1_[i][c] + 0.1 * grad_[i][c];
                m2_[i][c] = 0.999 * m2_[i][c] + 0.001 * grad_[i][c] * grad_[i][c];
                x[c] += lr_ * m1_[i][c] / (std::sqrt(m2_[i][c]) + 1e-12);
            }
            if (isSurface_[i]) constrain(i, x, old);
        }
    });
}

void JointMove::keepIfBest() {
    forHexes([&](std::size_t k) { hexScore_[k] = usableScaledJacobian(hexCoords(mesh_, hexes_[k])); });
    RegionScore now;
    for (std::size_t k = 0; k < H_; ++k) {
        now.inverted += !(hexScore_[k] > 0);
        now.min = std::min(now.min, hexScore_[k]);
    }
    if (betterRegion(now, best_)) {
        best_ = now;
        for (std::size_t i = 0; i < F_; ++i) bestAt_[i] = mesh_.nodes[static_cast<std::size_t>(free_[i])];
    }
}

void JointMove::constrain(std::size_t i, Vec3& p, const Vec3& fallback) const {
    const Vec3 q = projector_.project(mesh_.nodeClass[static_cast<std::size_t>(free_[i])].id, p);
    if (!finite(q)) {
        p = fallback;
        return;
    }
    const Vec3 d = p - q;
    const double n = norm(d);
    if (n > bound_[i]) p = q + (bound_[i] / n) * d;
}

void JointMove::settleSurfaceNodes() {
    for (std::size_t i = 0; i < F_; ++i) {
        if (!isSurface_[i]) continue;
        const Index v = free_[i];
        const auto sv = static_cast<std::size_t>(v);
        const Vec3 x = mesh_.nodes[sv];
        const Vec3 q = projector_.project(mesh_.nodeClass[sv].id, x);
        if (!finite(q)) continue;
        const double floor = 0.5 * std::min(minScaledJacobianAround(mesh_, topo_, v, x), opt_.target);
        double t = 1;
        for (int k = 0; k <= 6; ++k, t *= 0.5) {
            const Vec3 p = x + t * (q - x);
            const double m = minScaledJacobianAround(mesh_, topo_, v, p);
            if (m > 0 && m >= floor) {
                mesh_.nodes[sv] = p;
                break;
            }
        }
    }
}

}  // namespace

Region WorstHexPass::regionOf(Index h0, int rings) const {
    Region r;
    std::vector<Index>& free = r.free;
    std::vector<Index> layer;
    auto mark = [&](Index u) {
        if (std::find(free.begin(), free.end(), u) != free.end()) return false;
        free.push_back(u);
        return true;
    };
    for (Index u : mesh_.hexes[static_cast<std::size_t>(h0)]) {
        mark(u);
        layer.push_back(u);
    }
    for (int ring = 0; ring < rings; ++ring) {
        std::vector<Index> next;
        for (Index v : layer)
            for (const Index* h = topo_->nodeHexes.begin(static_cast<std::size_t>(v));
                 h != topo_->nodeHexes.end(static_cast<std::size_t>(v)); ++h)
                for (Index u : mesh_.hexes[static_cast<std::size_t>(*h)])
                    if (mark(u)) next.push_back(u);
        layer.swap(next);
    }
    std::sort(free.begin(), free.end());
    free.erase(std::remove_if(free.begin(), free.end(),
                              [&](Index u) {
                                  return !movable(u) ||
                                         mesh_.nodeClass[static_cast<std::size_t>(u)].kind == NodeKind::Curve;
                              }),
               free.end());
    for (Index v : free)
        for (const Index* h = topo_->nodeHexes.begin(static_cast<std::size_t>(v));
             h != topo_->nodeHexes.end(static_cast<std::size_t>(v)); ++h)
            r.hexes.push_back(*h);
    std::sort(r.hexes.begin(), r.hexes.end());
    r.hexes.erase(std::unique(r.hexes.begin(), r.hexes.end()), r.hexes.end());
    return r;
}

// Besides the region's nodes it writes only their entries of everMoved_ and
// released_ and its hexes' entries of sj_.
bool WorstHexPass::jointRelease(const Region& region, int iterations, bool byVolume) {
    if (region.free.empty()) return false;
    JointMove move(mesh_, *topo_, *projector_, opt_, region);
    if (!move.setUp() || !move.ascend(iterations, byVolume)) return false;
    move.settleSurfaceNodes();
    const double L = move.length();
    for (std::size_t i = 0; i < move.size(); ++i) {
        const auto sv = static_cast<std::size_t>(region.free[i]);
        if (norm(mesh_.nodes[sv] - move.start(i)) > 0) everMoved_[sv] = 1;
        if (move.isSurface(i)) {
            const Vec3 q = projector_->project(mesh_.nodeClass[sv].id, mesh_.nodes[sv]);
            if (!(norm(q - mesh_.nodes[sv]) <= 1e-6 * L)) released_[sv] = 1;
        }
    }
    for (Index h : region.hexes) sj_[static_cast<std::size_t>(h)] = usableScaledJacobian(hexCoords(mesh_, h));
    return true;
}

void WorstHexPass::jointAttempts(Index h0, const Region& region, JointCounts& counts) {
    const auto sh = static_cast<std::size_t>(h0);
    // One joint move of the region if h0 is still inverted and the move is
    // enabled (iterations > 0).
    auto attempt = [&](const Region& r, int iterations, bool byVolume) {
        if (sj_[sh] > 0 || iterations <= 0) return;
        counts.tried.fetch_add(1);
        if (jointRelease(r, iterations, byVolume)) counts.improved.fetch_add(1);
    };
    attempt(region, opt_.jointIterations, false);
    // Once more from there with longer stages (the corner of a plate one
    // cell thick needed it).
    attempt(region, opt_.jointRetryIterations, false);
    // On the determinants: where the frames around it are pressed flat the
    // scaled Jacobian's ascent has no direction (see frameValues).
    attempt(region, opt_.jointVolumeIterations, true);
    // The same on one ring only, where fewer frames compete for the soft
    // minimum (a knife-edge gyrus needed it). Its region is part of the
    // wider one, so the batch stays independent.
    if (!(sj_[sh] > 0) && opt_.jointRings > 1) {
        const Region narrow = regionOf(h0, 1);
        attempt(narrow, opt_.jointRetryIterations, false);
        attempt(narrow, opt_.jointVolumeIterations, true);
    }
}

std::vector<std::size_t> WorstHexPass::independentBatch(const std::vector<std::pair<Index, Region>>& pending,
                                                        std::vector<std::uint8_t>& claimed) const {
    std::vector<std::size_t> batch;
    std::vector<std::size_t> touched;
    for (std::size_t i = 0; i < pending.size(); ++i) {
        const auto& [h0, region] = pending[i];
        bool clash = claimed[static_cast<std::size_t>(h0)] != 0;
        for (Index h : region.hexes) clash = clash || claimed[static_cast<std::size_t>(h)] != 0;
        if (!clash) batch.push_back(i);
        for (Index h : region.hexes) {
            claimed[static_cast<std::size_t>(h)] = 1;
            touched.push_back(static_cast<std::size_t>(h));
        }
        claimed[static_cast<std::size_t>(h0)] = 1;
        touched.push_back(static_cast<std::size_t>(h0));
    }
    for (std::size_t h : touched) claimed[h] = 0;
    return batch;
}

// One inverted hex at a time in index order, or what is equivalent: regions
// that share no hex are independent (a region's move reads and writes only
// its own hexes' nodes), so each batch takes, in index order, the hexes whose
// region shares no hex with the region of any hex before them still waiting,
// and runs them in parallel. The result is the serial one for any number of
// threads. A joint move is kept when its region gets better, which can leave
// a neighbour inverted in place of the hex it was for (the region has as many
// inverted hexes, with a higher minimum): such hexes get their own turn in a
// further pass.
void WorstHexPass::jointMoves() {
    const Stopwatch watch;
    JointCounts counts;
    std::vector<std::uint8_t> attempted(sj_.size(), 0);
    std::vector<std::uint8_t> claimed(sj_.size(), 0);
    for (int pass = 0; pass < opt_.jointPasses; ++pass) {
        std::vector<std::pair<Index, Region>> pending;
        for (std::size_t h = 0; h < sj_.size(); ++h)
            if (!(sj_[h] > 0) && !attempted[h]) {
                attempted[h] = 1;
                pending.emplace_back(static_cast<Index>(h), regionOf(static_cast<Index>(h), opt_.jointRings));
            }
        if (pending.empty()) break;
        while (!pending.empty()) {
            const std::vector<std::size_t> batch = independentBatch(pending, claimed);
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, batch.size(), 1), [&](const auto& range) {
                for (std::size_t b = range.begin(); b != range.end(); ++b)
                    jointAttempts(pending[batch[b]].first, pending[batch[b]].second, counts);
            });
            std::vector<std::pair<Index, Region>> later;
            std::size_t b = 0;
            for (std::size_t i = 0; i < pending.size(); ++i) {
                if (b < batch.size() && batch[b] == i) ++b;
                else later.push_back(std::move(pending[i]));
            }
            pending.swap(later);
        }
    }
    res_.jointRegionsImproved = counts.improved.load();
    res_.jointRegionsTried = counts.tried.load();
    res_.jointSeconds = watch.seconds();
    settledKind_ = -1;
    // The joint move evens out the worst frames of the region; the compass
    // rounds then lift the hexes around it towards the target.
    if (res_.jointRegionsImproved > 0) roundsUntilStill({}, 0.33, 0.35);
}

}  // namespace isohex::smoothing::detail

// The smoother's untangling phase: Knupp's measure minimised node by node over
// the movable nodes near the inverted hexes, the region widened ring by ring
// when it stalls.
#include <algorithm>
#include <cmath>

#include "Smoother.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"

namespace isohex::smoothing::detail {

bool Smoother::untangleRound(bool guard, std::size_t before) {
    guarded_ = guard && opt_.untangleKeepsValidCorners;
    // An unguarded round may have to be undone: moveNode logs where each node
    // it moves first was (the moved nodes only, not a copy of every position).
    if (!guarded_) undo_ = std::make_unique<UndoLog>(mesh_.nodeCount());
    untanglePhase();
    guarded_ = opt_.untangleKeepsValidCorners;
    const std::unique_ptr<UndoLog> undo = std::move(undo_);
    if (!undo || invertedNow() <= before) return true;
    for (const auto& entries : undo->entries)
        for (const auto& [v, p] : entries)
            if (p != mesh_.nodes[static_cast<std::size_t>(v)]) moveNode(static_cast<std::size_t>(v), p);
    return false;
}

void Smoother::buildRegion(UntangleRegion& region, int rings, const std::vector<std::uint8_t>& inverted) const {
    const std::size_t H = mesh_.hexCount();
    for (Index v : region.nodes) region.inRegion[static_cast<std::size_t>(v)] = 0;
    for (Index h : region.hexes) region.hexInRegion[static_cast<std::size_t>(h)] = 0;
    region.nodes.clear();
    region.hexes.clear();
    auto add = [&](Index u) {
        const Mode m = mode_[static_cast<std::size_t>(u)];
        if (m != Mode::Frozen && (m != Mode::Curve || releaseSurface_) && !region.inRegion[static_cast<std::size_t>(u)]) {
            region.inRegion[static_cast<std::size_t>(u)] = 1;
            region.nodes.push_back(u);
        }
    };
    for (std::size_t h = 0; h < H; ++h)
        if (inverted[h])
            for (Index u : mesh_.hexes[h]) add(u);
    std::size_t layerStart = 0;
    for (int ring = 0; ring < rings; ++ring) {
        const std::size_t layerEnd = region.nodes.size();
        for (std::size_t i = layerStart; i < layerEnd; ++i) {
            const auto v = static_cast<std::size_t>(region.nodes[i]);
            for (const Index* h = topo_.nodeHexes.begin(v); h != topo_.nodeHexes.end(v); ++h)
                for (Index u : mesh_.hexes[static_cast<std::size_t>(*h)]) add(u);
        }
        layerStart = layerEnd;
    }
    region.lists.assign(colouring_.classes.size(), {});
    for (Index v : region.nodes) {
        region.lists[static_cast<std::size_t>(colouring_.colour[static_cast<std::size_t>(v)])].push_back(v);
        for (const Index* h = topo_.nodeHexes.begin(v); h != topo_.nodeHexes.end(v); ++h)
            if (!region.hexInRegion[static_cast<std::size_t>(*h)]) {
                region.hexInRegion[static_cast<std::size_t>(*h)] = 1;
                region.hexes.push_back(*h);
            }
    }
    for (auto& l : region.lists) std::sort(l.begin(), l.end());
}

// Knupp's measure is convex and the determinants affine along the step, so a
// shorter step still lowers the measure and keeps valid corners valid.
bool Smoother::withinRelease(std::size_t sv, const Vector3& d, Vec3& to) const {
    // every surface and curve node has an anchor (anchorReleasedNodes)
    const auto slot = static_cast<std::size_t>(
        std::lower_bound(anchorNodes_.begin(), anchorNodes_.end(), static_cast<Index>(sv)) - anchorNodes_.begin());
    const Vec3& a = anchor_[slot];
    const Vec3& x = mesh_.nodes[sv];
    double t = 1;
    for (int k = 0; k <= 6; ++k, t *= 0.5) {
        to = displaced(x, t * d);
        const double dx = to[0] - a[0], dy = to[1] - a[1], dz = to[2] - a[2];
        if (std::sqrt(dx * dx + dy * dy + dz * dz) <= releaseLimit_ * anchorLength_[slot]) break;
    }
    return !(t < 1.0 / 64);
}

bool Smoother::withinTravel(std::size_t sv, bool onSurface, Vec3& to) const {
    const double cap = opt_.untangleMaxTravel * refLength_[sv];
    auto far = [&](const Vec3& p) {
        const double dx = p[0] - start_[sv][0], dy = p[1] - start_[sv][1], dz = p[2] - start_[sv][2];
        return dx * dx + dy * dy + dz * dz > cap * cap;
    };
    if (!far(to)) return true;
    if (onSurface && !releaseSurface_) return false;
    const Vec3& x = mesh_.nodes[sv];
    const Vector3 d = offset(to, x);
    double t = 0.5;
    for (int k = 0; k < 6 && far(to = displaced(x, t * d)); ++k) t *= 0.5;
    return !far(to);
}

bool Smoother::untangleMove(Index v) {
    const auto sv = static_cast<std::size_t>(v);
    const bool onSurface = mode_[sv] == Mode::Surface || mode_[sv] == Mode::Curve;
    const Visit r = onSurface && !releaseSurface_ ? untangleSurfaceStep(v, buffers_->local())
                                                  : untangleStep(v, buffers_->local());
    if (r.move.steps == 0) return false;
    Vec3 to = r.position;
    // A released node stays within releaseLimit_ edge lengths of where it
    // was on the surface: the step is shortened (by halves) until it does.
    if (onSurface && releaseSurface_ && !withinRelease(sv, r.move.displacement, to)) return false;
    if (!withinTravel(sv, onSurface, to)) return false;
    if (onSurface && releaseSurface_) released_[sv] = 1;
    moveNode(sv, to);
    everMoved_[sv] = 1;
    touched_[sv] = 1;
    return true;
}

// Only hexes touching the region can have changed.
bool Smoother::refreshInverted(const UntangleRegion& region, std::vector<std::uint8_t>& inverted) const {
    std::atomic<bool> flipped{false};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, region.hexes.size(), 1024), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const auto h = static_cast<std::size_t>(region.hexes[i]);
            const std::uint8_t now = !(minJacobianDeterminant(hexCoords(mesh_, region.hexes[i])) > 0);
            if (now != inverted[h]) {
                inverted[h] = now;
                flipped.store(true, std::memory_order_relaxed);
            }
        }
    });
    return flipped.load();
}

void Smoother::untanglePhase() {
    const Stopwatch watch;
    const std::size_t N = mesh_.nodeCount(), H = mesh_.hexCount();
    std::size_t count = invertedNow();
    std::vector<std::uint8_t> inverted = hexInverted_;
    UntangleRegion region;
    region.inRegion.assign(N, 0);
    region.hexInRegion.assign(H, 0);
    // An untangling visit is a function of where the nodes of the node's
    // hexes are (the phase's flags, anchors and start positions stay put), so
    // a node whose visit moved nothing, and none of whose hexes' nodes moved
    // since, is `settled` and skipped: the outer rings of a grown region are
    // mostly such nodes. Bit for bit the result without the skip.
    std::vector<std::uint8_t> settled(N, 0);
    std::size_t best = count;
    int stall = 0, rings = 0, polish = 0;
    buildRegion(region, rings, inverted);
    for (int sweep = 0; sweep < opt_.maxUntangleSweeps && (count > 0 || polish < opt_.untanglePolishSweeps); ++sweep) {
        if (count == 0) ++polish;
        bool grown = false;
        sweepColours(region.lists, [&](Index v) {
            const auto sv = static_cast<std::size_t>(v);
            if (settled[sv]) return;
            if (untangleMove(v)) clearAround(mesh_, topo_.nodeHexes, v, settled);  // nodes sharing a hex may move now
            else settled[sv] = 1;
        });
        ++result_.untangleSweeps;
        const bool flipped = refreshInverted(region, inverted);
        count = static_cast<std::size_t>(std::count(inverted.begin(), inverted.end(), std::uint8_t{1}));
        report("untangle", static_cast<double>(sweep + 1) / opt_.maxUntangleSweeps);
        if (count == 0) continue;  // keep the region: polish it towards det >= beta
        if (count < best) {
            best = count;
            stall = 0;
        } else if (++stall >= 2) {
            // Stuck: give the inverted hexes more room by freeing one more ring.
            if (rings >= opt_.maxUntangleGrowth) break;
            ++rings;
            stall = 0;
            grown = true;
        }
        // The region depends on the inverted hexes and the rings only.
        if (flipped || grown) buildRegion(region, rings, inverted);
    }
    report("untangle", 1.0);
    result_.untangleSeconds += watch.seconds();
}

}  // namespace isohex::smoothing::detail

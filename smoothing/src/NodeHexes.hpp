#pragma once
// Internal to smoothing/: the scaled Jacobians of the hexes around one node as
// that node moves (NodeHexes), and their summary for comparing two positions
// (Around), as the worst-hex pass's compass and gradient searches use them.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "isohex/core/HexCell.hpp"
#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex::smoothing::detail {

using namespace vec;

// A projector answers a non-finite point where it cannot project.
inline bool finite(const Vec3& p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

// The hexes around node v with v at p, summarised for comparing positions.
struct Around {
    int inverted = 0;  // scaled Jacobian <= 0 (a corner or the centre)
    double min = std::numeric_limits<double>::infinity();
    double shortfall = 0;  // summed squared shortfall below the target
    double sum = 0;        // summed scaled Jacobians
};

// The scaled Jacobians of the hexes around one node as the node moves, for
// the compass searches, which try many positions of the same node. Of a
// hex's 9 frames (centre, corners) the node enters 5; the other 4 corner
// frames are evaluated once, at construction. The frames go through core's
// pieces of scaledJacobian, so the values are usableScaledJacobian's to the
// last bit.
class NodeHexes {
public:
    NodeHexes(const HexMesh& mesh, const Topology& topo, Index v) {
        const auto sv = static_cast<std::size_t>(v);
        for (const Index* h = topo.nodeHexes.begin(sv); h != topo.nodeHexes.end(sv); ++h) {
            Entry e;
            e.hex = *h;
            e.x = hexCoords(mesh, *h);
            const Hex& hx = mesh.hexes[static_cast<std::size_t>(*h)];
            for (int i = 0; i < 8 && e.local < 0; ++i)
                if (hx[static_cast<std::size_t>(i)] == v) e.local = i;
            if (e.local < 0) continue;
            for (int k = 0; k < 8; ++k) {
                if (involves(k, e.local)) continue;
                const double f = cornerFrame(e.x, k);
                if (f == kScaledJacobianCollapsed) e.collapsed = true;
                e.fixedMin = std::min(e.fixedMin, f);
            }
            entries_.push_back(e);
        }
    }
    std::size_t size() const { return entries_.size(); }
    Index hex(std::size_t k) const { return entries_[k].hex; }
    // usableScaledJacobian of the k-th hex with the node at p. (The compass
    // searches' hot path: it evaluates the same 5 frames as forMovingFrames
    // without their columns and coefficients, which made the pass 15-20%
    // slower when it went through it.)
    // It also notes, for summedGradient at the same p, which moving frame
    // gave the minimum (the gradient ascent of the mean rounds asks for the
    // gradient where the last value()s were taken: at the start of a visit
    // and after each accepted step).
    double value(std::size_t k, const Vec3& p) const {
        const Entry& e = entries_[k];
        if (e.collapsed) return -2.0;
        HexCoords x = e.x;
        x[static_cast<std::size_t>(e.local)] = p;
        e.lowestAt = p;
        e.lowest = kCollapsedFrame;
        const std::array<Vec3, 3> axes = centreAxes(x);
        double f = frameScaledJacobian(axes[0], axes[1], axes[2]);
        if (f == kScaledJacobianCollapsed) return -2.0;
        // (std::min(best, f) is f exactly when f < best: the frame that gives
        // best is the first strictly below the ones before it, as in
        // summedGradient's search.)
        int lowest = kFixedFrames;
        if (f < e.fixedMin) lowest = kCentreFrame;
        double best = std::min(e.fixedMin, f);
        for (int c = 0; c < 8; ++c) {
            if (!involves(c, e.local)) continue;
            f = cornerFrame(x, c);
            if (f == kScaledJacobianCollapsed) return -2.0;
            if (f < best) lowest = c;
            best = std::min(best, f);
        }
        e.lowest = lowest;
        const double sj = clampScaledJacobian(best);
        return scaledJacobianCollapsed(sj) ? -2.0 : sj;
    }

    // Gradient of the summed value(k, .) over the node's hexes at p: per
    // hex, the gradient of the frame that gives its minimum when it is one
    // the node enters, else nothing (a collapsed frame, or one of the 4 that
    // do not move).
    Vec3 summedGradient(const Vec3& p) const {
        Vec3 g{0, 0, 0};
        for (const Entry& e : entries_) {
            if (e.collapsed) continue;
            Frame lowest{};
            bool ok = true, moving = false;
            if (e.lowest != kUnknownFrame && std::memcmp(&e.lowestAt, &p, sizeof p) == 0) {
                // value() at p found the frame already: build that one only
                ok = e.lowest != kCollapsedFrame;
                moving = ok && e.lowest != kFixedFrames;
                if (moving) lowest = movingFrame(e, p, e.lowest);
            } else {
                double bestValue = e.fixedMin;
                ok = forMovingFrames(e, p, [&](const Frame& fr) {
                    if (fr.value < bestValue) {
                        bestValue = fr.value;
                        lowest = fr;
                        moving = true;
                    }
                    return true;
                });
            }
            if (!ok || !moving) continue;
            const Vec3& a = lowest.col[0];
            const Vec3& b = lowest.col[1];
            const Vec3& c = lowest.col[2];
            const double la = dot(a, a), lb = dot(b, b), lc = dot(c, c);
            const double len = std::sqrt(la * lb * lc);
            const double s = dot(a, cross(b, c)) / len;
            const std::array<Vec3, 3> d{(1.0 / len) * cross(b, c) - (s / la) * a,
                                        (1.0 / len) * cross(c, a) - (s / lb) * b,
                                        (1.0 / len) * cross(a, b) - (s / lc) * c};
            Vec3 gh{0, 0, 0};
            for (std::size_t j = 0; j < 3; ++j) gh = gh + lowest.coef[j] * d[j];
            g = g + gh;
        }
        return g;
    }

    // The shortest edge at the node with the node at p.
    double shortestEdge(const Vec3& p) const {
        double m = std::numeric_limits<double>::infinity();
        for (const Entry& e : entries_)
            for (int n : hexcell::kCornerNeighbours[static_cast<std::size_t>(e.local)])
                m = std::min(m, norm(e.x[static_cast<std::size_t>(n)] - p));
        return m;
    }

private:
    // Which frame of an entry gave its minimum at lowestAt: a corner 0..7,
    // the centre, none of the moving ones, a collapsed frame, or not known.
    static constexpr int kCentreFrame = 8, kFixedFrames = -1, kCollapsedFrame = -2, kUnknownFrame = -3;
    struct Entry {
        Index hex = kNone;
        HexCoords x;
        int local = -1;
        double fixedMin = kScaledJacobianCollapsed;
        bool collapsed = false;
        mutable int lowest = kUnknownFrame;  // as of the last value() of this entry
        mutable Vec3 lowestAt{};
    };
    static bool involves(int corner, int node) {
        if (corner == node) return true;
        for (int n : hexcell::kCornerNeighbours[static_cast<std::size_t>(corner)])
            if (n == node) return true;
        return false;
    }
    static double cornerFrame(const HexCoords& x, int k) {
        const auto& nb = hexcell::kCornerNeighbours[static_cast<std::size_t>(k)];
        return frameScaledJacobian(x[nb[0]] - x[k], x[nb[1]] - x[k], x[nb[2]] - x[k]);
    }
    // A frame the node enters: its columns, the node's coefficient in each
    // and its scaled Jacobian.
    struct Frame {
        std::array<Vec3, 3> col;
        std::array<double, 3> coef;
        double value;
    };
    // One of those frames (kCentreFrame or a corner), as forMovingFrames
    // builds it, without its value.
    static Frame movingFrame(const Entry& e, const Vec3& p, int which) {
        HexCoords x = e.x;
        const int l = e.local;
        x[static_cast<std::size_t>(l)] = p;
        Frame fr{};
        if (which == kCentreFrame) {
            fr.col = centreAxes(x);
            fr.coef = centreCoefficients(l);
            return fr;
        }
        const auto& nb = hexcell::kCornerNeighbours[static_cast<std::size_t>(which)];
        const auto sc = static_cast<std::size_t>(which);
        for (std::size_t j = 0; j < 3; ++j) {
            fr.col[j] = x[static_cast<std::size_t>(nb[j])] - x[sc];
            fr.coef[j] = which == l ? -1.0 : (nb[j] == l ? 1.0 : 0.0);
        }
        return fr;
    }
    static std::array<double, 3> centreCoefficients(int l) {
        return {(l == 1 || l == 2 || l == 5 || l == 6) ? 1.0 : -1.0, (l == 2 || l == 3 || l == 6 || l == 7) ? 1.0 : -1.0,
                l >= 4 ? 1.0 : -1.0};
    }
    // Calls f for the 5 frames of entry e that move with the node, with the
    // node at p: the centre, then the corners in order (the frames value()
    // takes the minimum of). Stops and returns false at a collapsed frame, or
    // when f returns false.
    template <class F>
    static bool forMovingFrames(const Entry& e, const Vec3& p, F&& f) {
        HexCoords x = e.x;
        const int l = e.local;
        x[static_cast<std::size_t>(l)] = p;
        Frame fr;
        fr.col = centreAxes(x);
        fr.coef = centreCoefficients(l);
        fr.value = frameScaledJacobian(fr.col[0], fr.col[1], fr.col[2]);
        if (fr.value == kScaledJacobianCollapsed || !f(fr)) return false;
        for (int c = 0; c < 8; ++c) {
            if (!involves(c, l)) continue;
            const auto& nb = hexcell::kCornerNeighbours[static_cast<std::size_t>(c)];
            const auto sc = static_cast<std::size_t>(c);
            for (std::size_t j = 0; j < 3; ++j) {
                fr.col[j] = x[static_cast<std::size_t>(nb[j])] - x[sc];
                fr.coef[j] = c == l ? -1.0 : (nb[j] == l ? 1.0 : 0.0);
            }
            fr.value = frameScaledJacobian(fr.col[0], fr.col[1], fr.col[2]);
            if (fr.value == kScaledJacobianCollapsed || !f(fr)) return false;
        }
        return true;
    }
    std::vector<Entry> entries_;
};

// Adds the k-th hex's value s to a summary (floors: see around).
inline void include(Around& a, std::size_t k, double s, double target, const double* floors) {
    a.inverted += floors ? !(s >= floors[k]) : !(s > 0);
    a.min = std::min(a.min, s);
    a.sum += s;
    if (s < target) a.shortfall += (target - s) * (target - s);
}

// The node's hexes with the node at p, summarised. With `floors` (the mean
// rounds: floors[k] is the least the k-th hex may have), `inverted` counts
// the hexes under their floor instead of those with no positive value.
inline Around around(const NodeHexes& nh, const Vec3& p, double target, const double* floors = nullptr) {
    Around a;
    for (std::size_t k = 0; k < nh.size(); ++k) include(a, k, nh.value(k, p), target, floors);
    return a;
}

// As around, for a compass trial that only counts if it beats `bar`: it
// stops at the first hex that settles the trial's refusal (a hex under its
// floor in the mean rounds; in the max-min rounds, more hexes inverted than
// `bar`, or as many with a smaller value than bar's minimum). Counts only grow
// and the minimum only falls as hexes are added, so the summary of the hexes
// seen so far is refused by `better` and by the mean rounds' test just as
// the whole one would be, and the search takes the same path. `first` (in and
// out, -1 for none): the hex that refused the last trial, tried first, since
// the next trial of the visit is often refused by the same hex. A trial that
// is not refused gets the summary `around` gives, the sums taken in the same
// order.
inline Around aroundUnless(const NodeHexes& nh, const Vec3& p, double target, const double* floors, const Around& bar,
                    int& first) {
    Around a;
    auto refused = [&] {
        if (floors) return a.inverted > 0;
        return a.inverted > bar.inverted || (a.inverted == bar.inverted && a.min < bar.min);
    };
    const std::size_t n = nh.size();
    std::array<double, 64> stored;
    std::vector<double> more;
    double* values = stored.data();
    if (n > stored.size()) {
        more.resize(n);
        values = more.data();
    }
    if (first >= 0 && static_cast<std::size_t>(first) < n) {
        const auto k = static_cast<std::size_t>(first);
        values[k] = nh.value(k, p);
        include(a, k, values[k], target, floors);
        if (refused()) return a;
    }
    for (std::size_t k = 0; k < n; ++k) {
        if (static_cast<int>(k) == first) continue;
        values[k] = nh.value(k, p);
        include(a, k, values[k], target, floors);
        if (refused()) {
            first = static_cast<int>(k);
            return a;
        }
    }
    if (first < 0) return a;  // taken in order already
    a = Around{};
    for (std::size_t k = 0; k < n; ++k) include(a, k, values[k], target, floors);
    return a;
}

inline bool better(const Around& trial, const Around& current) {
    if (trial.inverted != current.inverted) return trial.inverted < current.inverted;
    if (trial.min > current.min + 1e-12) return true;
    return trial.min >= current.min && trial.shortfall < current.shortfall * (1 - 1e-9) - 1e-15;
}

}  // namespace isohex::smoothing::detail

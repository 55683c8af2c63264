#include "isohex/smoothing/WorstHexes.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <atomic>
#include <chrono>
#include <limits>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/core/HexCell.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/VecMath.hpp"
#include "isohex/smoothing/Colouring.hpp"

namespace isohex::smoothing {

namespace {

using namespace vec;

// A projector answers a non-finite point where it cannot project.
bool finite(const Vec3& p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

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
    double value(std::size_t k, const Vec3& p) const {
        const Entry& e = entries_[k];
        if (e.collapsed) return -2.0;
        HexCoords x = e.x;
        x[static_cast<std::size_t>(e.local)] = p;
        const std::array<Vec3, 3> axes = centreAxes(x);
        double f = frameScaledJacobian(axes[0], axes[1], axes[2]);
        if (f == kScaledJacobianCollapsed) return -2.0;
        double best = std::min(e.fixedMin, f);
        for (int c = 0; c < 8; ++c) {
            if (!involves(c, e.local)) continue;
            f = cornerFrame(x, c);
            if (f == kScaledJacobianCollapsed) return -2.0;
            best = std::min(best, f);
        }
        const double sj = clampScaledJacobian(best);
        return sj > 1.0 + 1e-9 ? -2.0 : sj;
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
            double bestValue = e.fixedMin;
            bool moving = false;
            const bool ok = forMovingFrames(e, p, [&](const Frame& fr) {
                if (fr.value < bestValue) {
                    bestValue = fr.value;
                    lowest = fr;
                    moving = true;
                }
                return true;
            });
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
    struct Entry {
        Index hex = kNone;
        HexCoords x;
        int local = -1;
        double fixedMin = kScaledJacobianCollapsed;
        bool collapsed = false;
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
        fr.coef = {(l == 1 || l == 2 || l == 5 || l == 6) ? 1.0 : -1.0, (l == 2 || l == 3 || l == 6 || l == 7) ? 1.0 : -1.0,
                   l >= 4 ? 1.0 : -1.0};
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
void include(Around& a, std::size_t k, double s, double target, const double* floors) {
    a.inverted += floors ? !(s >= floors[k]) : !(s > 0);
    a.min = std::min(a.min, s);
    a.sum += s;
    if (s < target) a.shortfall += (target - s) * (target - s);
}

// The node's hexes with the node at p, summarised. With `floors` (the mean
// rounds: floors[k] is the least the k-th hex may have), `inverted` counts
// the hexes under their floor instead of those with no positive value.
Around around(const NodeHexes& nh, const Vec3& p, double target, const double* floors = nullptr) {
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
Around aroundUnless(const NodeHexes& nh, const Vec3& p, double target, const double* floors, const Around& bar,
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

bool better(const Around& trial, const Around& current) {
    if (trial.inverted != current.inverted) return trial.inverted < current.inverted;
    if (trial.min > current.min + 1e-12) return true;
    return trial.min >= current.min && trial.shortfall < current.shortfall * (1 - 1e-9) - 1e-15;
}


// ---------------------------------------------------------------------------
// Joint release: all movable nodes within a few rings of an inverted hex move
// together.
//
// The compass search moves one node at a time and never accepts a move that
// leaves more hexes inverted around that node. Where a pit or pocket of the
// isosurface is much smaller than an element (ch2bet: a background pocket of
// about one voxel under a one-cell pit of the dual-contouring surface at
// 4 mm), the pillow hexes of the pit's floor and walls are coupled: lifting
// one above zero tips the next below, so node by node they stall at about
// -1e-4, which is what the report showed. Moving the nodes of two rings
// jointly (surface nodes off the surface by at most releaseDistance edge
// lengths, as in the release rounds) finds valid configurations there (a
// python experiment first: with the surface nodes held within 0.1 voxel no
// positive one was found; with 1 voxel, at 4 mm, the whole region > 0.3).
//
// Method: gradient ascent (Adam-style scaling per coordinate) on a soft
// minimum (log-sum-exp) of every scaled-Jacobian frame of the hexes touching
// a free node, with the softness lowered in stages; surface nodes are put
// back within their bound after each step. The best iterate is kept only if
// it beats the start on (inverted hexes, smallest scaled Jacobian) over
// those hexes, so nothing gets worse and no hex outside the region changes.
// Everything here is serial: the result does not depend on the thread count.

// The 9 frames (centre, corners 0..7) as signed node combinations: frame f,
// column j = sum over the hex's nodes of kFrame[f][j][n] * x[n].
struct FrameTable {
    std::array<std::array<std::array<double, 8>, 3>, 9> c{};
    FrameTable() {
        const int pos[3][4] = {{1, 2, 5, 6}, {2, 3, 6, 7}, {4, 5, 6, 7}};
        const int neg[3][4] = {{0, 3, 4, 7}, {0, 1, 4, 5}, {0, 1, 2, 3}};
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 4; ++i) {
                c[0][static_cast<std::size_t>(j)][static_cast<std::size_t>(pos[j][i])] = 1;
                c[0][static_cast<std::size_t>(j)][static_cast<std::size_t>(neg[j][i])] = -1;
            }
        for (int k = 0; k < 8; ++k)
            for (int j = 0; j < 3; ++j) {
                const auto sk = static_cast<std::size_t>(k), sj = static_cast<std::size_t>(j);
                c[sk + 1][sj][static_cast<std::size_t>(hexcell::kCornerNeighbours[sk][sj])] += 1;
                c[sk + 1][sj][sk] -= 1;
            }
    }
};

const FrameTable& frameTable() {
    static const FrameTable t;
    return t;
}

// The same table without its zeros: per frame and column, the nodes with a
// non-zero coefficient in increasing order (8 for the centre frame, 2 for a
// corner's). Sums taken over it add the same terms in the same order as a
// loop over all 8 nodes that skips the zeros, so the results are the same
// to the last bit; the joint release forms every frame of its region at
// every step, and the dense loop was a good part of its time.
struct SparseFrameTable {
    struct Term {
        std::uint8_t node;
        double coef;
    };
    std::array<std::array<std::array<Term, 8>, 3>, 9> terms{};
    std::array<std::array<std::uint8_t, 3>, 9> count{};
    SparseFrameTable() {
        const FrameTable& t = frameTable();
        for (std::size_t f = 0; f < 9; ++f)
            for (std::size_t j = 0; j < 3; ++j)
                for (std::size_t n = 0; n < 8; ++n)
                    if (t.c[f][j][n] != 0) terms[f][j][count[f][j]++] = {static_cast<std::uint8_t>(n), t.c[f][j][n]};
    }
};

const SparseFrameTable& sparseFrameTable() {
    static const SparseFrameTable t;
    return t;
}

// What the soft minimum needs of each of a hex's 9 frames: the scaled
// Jacobian and, to differentiate it, the columns, their lengths and their
// cross products. frameValues fills it once per step; frameGradients reuses
// it instead of forming the frames again.
struct FrameState {
    std::array<Vec3, 3> col, cross;  // cross = b x c, c x a, a x b
    double la, lb, lc, len, s;
    bool collapsed;
};
using HexFrames = std::array<FrameState, 9>;

// What the soft minimum is taken of, per frame: the scaled Jacobian (scale
// 0), or the determinant times `scale` (the frame's columns as in the
// corners; the centre frame's, sums of four edges, count a quarter each).
// The scaled Jacobian does not see size, so a region whose worst frames have
// been evened out at zero (a node on the plane of its neighbours, the
// corner hex of a sheet pressed flat against the surface) gives the ascent
// no direction that opens them; the determinant grows with the frame, so its
// soft minimum pushes the flat frames open first. Fills `out` with the
// scaled Jacobian of each of the 9 frames (-2 for a collapsed frame), or with
// scale > 0 its scaled determinant.
void frameValues(const HexCoords& x, HexFrames& out, double scale = 0) {
    const SparseFrameTable& t = sparseFrameTable();
    for (std::size_t f = 0; f < 9; ++f) {
        FrameState& st = out[f];
        for (std::size_t j = 0; j < 3; ++j) {
            Vec3 v{0, 0, 0};
            for (std::size_t i = 0; i < t.count[f][j]; ++i) v = v + t.terms[f][j][i].coef * x[t.terms[f][j][i].node];
            st.col[j] = v;
        }
        st.cross = {cross(st.col[1], st.col[2]), cross(st.col[2], st.col[0]), cross(st.col[0], st.col[1])};
        if (scale > 0) {
            st.collapsed = false;
            st.s = dot(st.col[0], st.cross[0]) * (f == 0 ? scale / 64 : scale);
            continue;
        }
        st.la = norm(st.col[0]), st.lb = norm(st.col[1]), st.lc = norm(st.col[2]);
        st.len = st.la * st.lb * st.lc;
        st.collapsed = !(st.len > 1e-300);
        if (st.collapsed) {  // as bad as it gets, no direction
            st.s = -2;
            continue;
        }
        st.s = dot(st.col[0], st.cross[0]) / st.len;
    }
}

// Adds weight[f] * d s_f / d x_n to grad[n] for the hex's 8 nodes (s_f as
// frameValues computed it with the same scale).
void frameGradients(const HexFrames& frames, const double* weight, std::array<Vec3, 8>& grad, double scale = 0) {
    const SparseFrameTable& t = sparseFrameTable();
    for (std::size_t f = 0; f < 9; ++f) {
        const FrameState& st = frames[f];
        if (st.collapsed || weight[f] == 0) continue;
        std::array<Vec3, 3> g;
        if (scale > 0) {
            const double k = f == 0 ? scale / 64 : scale;  // d det / d column j = cross[j]
            g = {k * st.cross[0], k * st.cross[1], k * st.cross[2]};
        } else {
            g = {(1.0 / st.len) * st.cross[0] - (st.s / (st.la * st.la)) * st.col[0],
                 (1.0 / st.len) * st.cross[1] - (st.s / (st.lb * st.lb)) * st.col[1],
                 (1.0 / st.len) * st.cross[2] - (st.s / (st.lc * st.lc)) * st.col[2]};
        }
        for (std::size_t j = 0; j < 3; ++j)
            for (std::size_t i = 0; i < t.count[f][j]; ++i) {
                const auto& term = t.terms[f][j][i];
                grad[term.node] = grad[term.node] + (weight[f] * term.coef) * g[j];
            }
    }
}

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

}  // namespace

double usableScaledJacobian(const HexCoords& x) {
    const double s = scaledJacobian(x);
    return s > 1.0 + 1e-9 ? -2.0 : s;
}

double minScaledJacobianAround(const HexMesh& mesh, const Topology& topo, Index v, const Vec3& p) {
    return around(NodeHexes(mesh, topo, v), p, 0.0).min;
}

Vec3 summedScaledJacobianGradient(const HexMesh& mesh, const Topology& topo, Index v, const Vec3& p) {
    return NodeHexes(mesh, topo, v).summedGradient(p);
}

double meanEdgeLengthAt(const HexMesh& mesh, const Topology& topo, Index v) {
    double sum = 0;
    int count = 0;
    const auto sv = static_cast<std::size_t>(v);
    const Vec3& x = mesh.nodes[sv];
    for (const Index* h = topo.nodeHexes.begin(sv); h != topo.nodeHexes.end(sv); ++h) {
        const Hex& hx = mesh.hexes[static_cast<std::size_t>(*h)];
        for (int i = 0; i < 8; ++i) {
            if (hx[static_cast<std::size_t>(i)] != v) continue;
            for (int j : hexcell::kCornerNeighbours[static_cast<std::size_t>(i)]) {
                sum += norm(mesh.nodes[static_cast<std::size_t>(hx[static_cast<std::size_t>(j)])] - x);
                ++count;
            }
        }
    }
    return count ? sum / count : 0.0;
}

std::vector<Vec3> surfaceNormals(const HexMesh& mesh, const Topology& topo) {
    std::vector<Vec3> n(mesh.nodeCount(), Vec3{0, 0, 0});
    for (const Quad& q : topo.quads) {
        double sign = 1;  // quad nodes are in hex[0]'s order: the normal points out of hex[0]
        if (!q.boundary()) {
            const std::int32_t m0 = mesh.material[static_cast<std::size_t>(q.hex[0])];
            const std::int32_t m1 = mesh.material[static_cast<std::size_t>(q.hex[1])];
            if (m0 == m1) continue;
            if (m0 > m1) sign = -1;
        }
        const auto& x = mesh.nodes;
        const Vec3 a = sign * cross(x[q.nodes[2]] - x[q.nodes[0]], x[q.nodes[3]] - x[q.nodes[1]]);
        for (Index v : q.nodes) n[static_cast<std::size_t>(v)] = n[static_cast<std::size_t>(v)] + a;
    }
    for (Vec3& a : n) {
        const double l = norm(a);
        if (l > 0) a = (1.0 / l) * a;
    }
    return n;
}

WorstHexResult raiseWorstHexes(HexMesh& mesh, const SurfaceProjector* projector, const WorstHexOptions& opt,
                               const Topology* topology) {
    WorstHexResult res;
    const std::size_t N = mesh.nodeCount();
    if (mesh.hexCount() == 0) return res;
    std::vector<double> sj = scaledJacobians(mesh);
    for (double& s : sj)
        if (s > 1.0 + 1e-9) s = -2.0;
    auto countBelow = [&] {
        return static_cast<std::size_t>(std::count_if(sj.begin(), sj.end(), [&](double s) { return s < opt.target; }));
    };
    res.minBefore = sj.empty() ? 0.0 : *std::min_element(sj.begin(), sj.end());
    res.belowBefore = countBelow();
    res.minAfter = res.minBefore;
    res.belowAfter = res.belowBefore;
    const bool meanRounds =
        opt.meanRounds > 0 && std::any_of(sj.begin(), sj.end(), [&](double s) { return s < opt.meanBelow; });
    if (res.belowBefore == 0 && !meanRounds && !(projector != nullptr && opt.returnPasses > 0)) return res;

    Topology own;
    if (!topology) own = buildTopology(mesh);
    else requireTopologyOf(mesh, *topology, "worst-hex pass");
    const Topology& topo = topology ? *topology : own;
    auto movable = [&](Index v) {
        const NodeClass& c = mesh.nodeClass[static_cast<std::size_t>(v)];
        // (Interior-classified nodes on the boundary, Fixed nodes and Curve
        // nodes where the projector knows no curve never move.)
        if (c.kind == NodeKind::Interior) return !topo.nodeOnBoundary[static_cast<std::size_t>(v)];
        if (c.kind == NodeKind::Curve) return projector != nullptr && projector->hasCurves() && c.id >= 0;
        return c.kind == NodeKind::Surface && projector != nullptr;
    };
    std::vector<std::uint8_t> everMoved(N, 0), released(N, 0);
    // How far p is from surface node v's surface (NaN where the projection
    // fails, so that a bound `!(offBy(..) <= b)` refuses it).
    auto offBy = [&](std::size_t v, const Vec3& p) { return norm(projector->project(mesh.nodeClass[v].id, p) - p); };
    // A compass visit is a function of where the nodes of the node's hexes
    // are (and of fixed data: its normal, the target, the projector), so a
    // node whose last visit in the same kind of round moved nothing, and none
    // of whose hexes' nodes moved since, would move nothing again: `settled`
    // marks such nodes and the rounds skip them. Rounds still pick and colour
    // their nodes as before, so the result is the one without the skip, bit
    // for bit. Cleared when the kind of round changes and after the joint
    // release, which moves nodes outside the rounds.
    std::vector<std::uint8_t> settled(N, 0);
    int settledKind = -1;
    // Directions of the compass search: the 6 axes and 8 cube diagonals in
    // 3-D; 8 directions 45 degrees apart in a tangent plane.
    std::vector<Vec3> dirs3;
    for (int i = 0; i < 3; ++i)
        for (int s = -1; s <= 1; s += 2) {
            Vec3 d{0, 0, 0};
            d[static_cast<std::size_t>(i)] = s;
            dirs3.push_back(d);
        }
    for (int a = -1; a <= 1; a += 2)
        for (int b = -1; b <= 1; b += 2)
            for (int c = -1; c <= 1; c += 2)
                dirs3.push_back((1.0 / std::sqrt(3.0)) * Vec3{double(a), double(b), double(c)});

    // The least each hex around a node may end with in the mean rounds and
    // the return step: its value now, or the target if it is above that; a
    // valid hex stays valid even with a target of 0.
    auto floorsOf = [&](const NodeHexes& nh) {
        std::vector<double> floors(nh.size());
        for (std::size_t k = 0; k < nh.size(); ++k) {
            const double s0 = sj[static_cast<std::size_t>(nh.hex(k))];
            floors[k] = s0 > 0 ? std::max(std::min(s0, opt.target), std::numeric_limits<double>::min()) : s0;
        }
        return floors;
    };
    // After node v moved: its hexes' entries of sj.
    auto refreshAround = [&](std::size_t v) {
        for (const Index* h = topo.nodeHexes.begin(v); h != topo.nodeHexes.end(v); ++h)
            sj[static_cast<std::size_t>(*h)] = usableScaledJacobian(hexCoords(mesh, *h));
    };

    // One node's compass search; true if it moved.
    // With `release`, a surface node moves in 3-D, off its surface, but stays
    // within releaseDistance local edge lengths of it. With `mean` (the mean
    // rounds), a trial is better when it raises the summed scaled Jacobian of
    // the node's hexes and leaves none of them below its floor: its value at
    // the start of the visit, or the target if it was above that.
    auto visit = [&](Index v, const std::vector<Vec3>& normal, bool release, bool mean = false, bool slack = false) {
        const auto sv = static_cast<std::size_t>(v);
        const bool surface = mesh.nodeClass[sv].kind == NodeKind::Surface;
        const bool curve = mesh.nodeClass[sv].kind == NodeKind::Curve;
        if (curve && release) return false;  // curve nodes stay on their curve
        // In the slack rounds a surface node moves in 3-D, off its surface by
        // at most surfaceSlack (not off a surface the projector leaves alone).
        const bool offSurface = surface && slack && projector->projectsOnto(mesh.nodeClass[sv].id);
        const bool onSurface = surface && !release && !offSurface;
        // The mean rounds step along the gradient of the summed scaled
        // Jacobian of the node's hexes (in its tangent plane on a surface),
        // halving the step until a position is better; a curve node keeps
        // the compass search along its curve.
        const bool ascend = mean && !curve;
        if (onSurface && !(norm(normal[sv]) > 0)) return false;
        std::vector<Vec3> dirs = dirs3;
        if (onSurface && !ascend) {
            const Vec3 n = normal[sv];
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
        // A curve node in the mean rounds: the 6 axes only, onto its curve
        // (the compass search there once covered every node, and the
        // diagonals as well cost 70% more time on ch2bet at 2 mm for 6% more
        // gain).
        if (mean && !onSurface) dirs.resize(6);
        const double L = meanEdgeLengthAt(mesh, topo, v);
        if (!(L > 0)) return false;
        const NodeHexes nh(mesh, topo, v);
        const std::vector<double> floors = mean ? floorsOf(nh) : std::vector<double>{};
        int refusedBy = -1;  // the hex that refused the last trial (aroundUnless)
        auto evaluate = [&](const Vec3& p) {
            return around(nh, p, opt.target, mean ? floors.data() : nullptr);
        };
        auto evaluateTrial = [&](const Vec3& p, const Around& bar) {
            return aroundUnless(nh, p, opt.target, mean ? floors.data() : nullptr, bar, refusedBy);
        };
        auto improves = [&](const Around& trial, const Around& current) {
            if (!mean) return better(trial, current);
            return trial.inverted == 0 && trial.sum > current.sum + 1e-12 * static_cast<double>(floors.size());
        };
        Around best = evaluate(mesh.nodes[sv]);
        // No edge at the node may end shorter than minEdge x L, or than it
        // was if it was shorter (see WorstHexOptions::minEdge).
        const double edgeFloor = std::min(nh.shortestEdge(mesh.nodes[sv]), opt.minEdge * L);
        auto edgesOk = [&](const Vec3& p) { return !(opt.minEdge > 0) || nh.shortestEdge(p) >= edgeFloor; };
        double step = (mean ? opt.meanFirstStep : opt.firstStep) * L;
        // Off the surface by at most surfaceSlack: longer steps cannot pass.
        if (offSurface) step = std::min(step, opt.surfaceSlack);
        const int maxMoves = mean ? opt.meanMovesPerVisit : opt.maxMovesPerVisit;
        int moves = 0;
        while (ascend && step >= opt.lastStep * L && moves < maxMoves) {
            Vec3 g = nh.summedGradient(mesh.nodes[sv]);
            if (onSurface) {
                const Vec3 nu = (1.0 / norm(normal[sv])) * normal[sv];
                g = g - dot(g, nu) * nu;
            }
            const double gn = norm(g);
            if (!(gn > 0) || !std::isfinite(gn)) break;
            const Vec3 d = (1.0 / gn) * g;
            bool moved = false;
            for (; step >= opt.lastStep * L; step *= 0.5) {
                Vec3 p = mesh.nodes[sv] + step * d;
                if (onSurface) p = projector->project(mesh.nodeClass[sv].id, p);
                if (!finite(p) || !edgesOk(p)) continue;
                const Around f = evaluateTrial(p, best);
                if (improves(f, best)) {
                    mesh.nodes[sv] = p;
                    best = f;
                    ++moves;
                    moved = true;
                    break;
                }
            }
            if (!moved) break;
        }
        while (!ascend && step >= opt.lastStep * L && moves < maxMoves) {
            Vec3 bestPos = mesh.nodes[sv];
            Around bestValue = best;
            for (const Vec3& d : dirs) {
                Vec3 p = mesh.nodes[sv] + step * d;
                if (onSurface) p = projector->project(mesh.nodeClass[sv].id, p);
                // a curve node: the 3-D trial point onto its curve (both ways along it)
                if (curve) p = projector->projectToCurve(mesh.nodeClass[sv].id, p);
                if (!finite(p)) continue;
                if (surface && release && !(offBy(sv, p) <= opt.releaseDistance * L)) continue;
                if (offSurface && !(offBy(sv, p) <= opt.surfaceSlack)) continue;
                if (!edgesOk(p)) continue;
                const Around f = evaluateTrial(p, bestValue);
                if (improves(f, bestValue)) {
                    bestValue = f;
                    bestPos = p;
                }
            }
            if (improves(bestValue, best)) {
                mesh.nodes[sv] = bestPos;
                best = bestValue;
                ++moves;
            } else {
                step *= 0.5;
            }
        }
        if (!moves) {
            settled[sv] = 1;
            return false;
        }
        everMoved[sv] = 1;
        if (surface && release) released[sv] = 1;
        refreshAround(sv);
        clearAround(mesh, topo.nodeHexes, v, settled);  // nodes sharing a hex with it may move now
        return true;
    };

    // Tangent planes from the surfaces as they are at the start (the nodes
    // move by fractions of an element).
    const std::vector<Vec3> normal = surfaceNormals(mesh, topo);
    // Rounds over the nodes of the hexes below the target until nothing moves;
    // then, if hexes are still inverted, rounds over theirs only, where
    // surface nodes may leave their surface (validity before fidelity: a fold
    // of the surface within one element cannot be opened along it).
    auto runRound = [&](bool release, bool mean = false, bool slack = false) {
        // The round's nodes: the movable nodes of the hexes it works on,
        // picked node by node in parallel (on the 1 mm brain the mean rounds
        // pick about 580 k nodes of 2 M; a serial pass over the hexes with a
        // sort took 0.16 s a round).
        const double below = mean ? opt.meanBelow : opt.target;
        std::vector<std::uint8_t> pick(N, 0);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, N, 4096), [&](const auto& r) {
            for (std::size_t v = r.begin(); v != r.end(); ++v) {
                bool in = false;
                for (const Index* h = topo.nodeHexes.begin(v); h != topo.nodeHexes.end(v) && !in; ++h) {
                    const double s = sj[static_cast<std::size_t>(*h)];
                    in = release ? !(s > 0) : s < below;
                }
                pick[v] = in && movable(static_cast<Index>(v));
            }
        });
        if (std::find(pick.begin(), pick.end(), std::uint8_t{1}) == pick.end()) return false;
        if (const int kind = 2 * release + mean + 4 * slack; kind != settledKind) {
            std::fill(settled.begin(), settled.end(), std::uint8_t{0});
            settledKind = kind;
        }
        // Nodes sharing no hex move at once: one colour class per parallel
        // loop, classes in order, so the result is the same for any number
        // of threads.
        const NodeColouring colouring = colourNodes(mesh, topo.nodeHexes, pick);
        std::atomic<bool> anyMove{false};
        for (const std::vector<Index>& cls : colouring.classes)
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, cls.size(), 16), [&](const auto& range) {
                for (std::size_t i = range.begin(); i != range.end(); ++i)
                    if (!settled[static_cast<std::size_t>(cls[i])] && visit(cls[i], normal, release, mean, slack))
                        anyMove = true;
            });
        ++res.rounds;
        return anyMove.load();
    };
    // Joint release around inverted hex h: returns true if the region got
    // better (fewer inverted hexes, or a larger smallest scaled Jacobian).
    // The region of inverted hex h0: its free nodes (movable non-curve nodes
    // within jointRings rings of h0) and the hexes around them, both sorted.
    // It depends on the connectivity only, not on where the nodes are.
    struct Region {
        std::vector<Index> free, hexes;
    };
    auto regionOf = [&](Index h0, int rings) {
        Region r;
        std::vector<Index>& free = r.free;
        std::vector<Index> layer;
        auto mark = [&](Index u) {
            if (std::find(free.begin(), free.end(), u) != free.end()) return false;
            free.push_back(u);
            return true;
        };
        for (Index u : mesh.hexes[static_cast<std::size_t>(h0)]) {
            mark(u);
            layer.push_back(u);
        }
        for (int ring = 0; ring < rings; ++ring) {
            std::vector<Index> next;
            for (Index v : layer)
                for (const Index* h = topo.nodeHexes.begin(static_cast<std::size_t>(v));
                     h != topo.nodeHexes.end(static_cast<std::size_t>(v)); ++h)
                    for (Index u : mesh.hexes[static_cast<std::size_t>(*h)])
                        if (mark(u)) next.push_back(u);
            layer.swap(next);
        }
        std::sort(free.begin(), free.end());
        free.erase(std::remove_if(free.begin(), free.end(),
                                  [&](Index u) {
                                      return !movable(u) ||
                                             mesh.nodeClass[static_cast<std::size_t>(u)].kind == NodeKind::Curve;
                                  }),
                   free.end());
        for (Index v : free)
            for (const Index* h = topo.nodeHexes.begin(static_cast<std::size_t>(v));
                 h != topo.nodeHexes.end(static_cast<std::size_t>(v)); ++h)
                r.hexes.push_back(*h);
        std::sort(r.hexes.begin(), r.hexes.end());
        r.hexes.erase(std::unique(r.hexes.begin(), r.hexes.end()), r.hexes.end());
        return r;
    };
    // Joint release of a region: returns true if it got better (fewer
    // inverted hexes, or a larger smallest scaled Jacobian). It reads and
    // writes only the region's free nodes, the nodes of its hexes and their
    // entries of sj, everMoved and released.
    auto jointRelease = [&](const Region& region, int iterations, bool byVolume) {
        const std::vector<Index>& free = region.free;
        const std::vector<Index>& hexes = region.hexes;
        if (free.empty()) return false;
        // Local numbering of the free nodes, their bounds and starting points.
        const std::size_t F = free.size();
        std::vector<Vec3> start(F);
        std::vector<double> bound(F, 0.0);
        std::vector<std::uint8_t> isSurface(F, 0);
        double L = 0;
        for (std::size_t i = 0; i < F; ++i) {
            const auto sv = static_cast<std::size_t>(free[i]);
            start[i] = mesh.nodes[sv];
            const double l = meanEdgeLengthAt(mesh, topo, free[i]);
            L += l / static_cast<double>(F);
            if (mesh.nodeClass[sv].kind == NodeKind::Surface) {
                isSurface[i] = 1;
                // A node the optimiser's own release left farther off may
                // stay as far off, but not go farther; one whose projection
                // fails already (more than a few voxels off) stays put.
                const Vec3 q = projector->project(mesh.nodeClass[sv].id, start[i]);
                const bool ok = finite(q);
                bound[i] = ok ? std::max(opt.releaseDistance * l, norm(q - start[i])) : -1;
            }
        }
        // (pinned nodes: kept in `free` for the numbering, never moved)
        std::vector<std::uint8_t> pinned(F, 0);
        for (std::size_t i = 0; i < F; ++i) pinned[i] = isSurface[i] && bound[i] < 0;
        if (!(L > 0)) return false;
        auto local = [&](Index v) {
            const auto it = std::lower_bound(free.begin(), free.end(), v);
            return it != free.end() && *it == v ? static_cast<std::ptrdiff_t>(it - free.begin()) : std::ptrdiff_t{-1};
        };
        // Each region hex's nodes in the local numbering (-1: not free).
        std::vector<std::array<std::ptrdiff_t, 8>> localNodes(hexes.size());
        for (std::size_t k = 0; k < hexes.size(); ++k)
            for (std::size_t n = 0; n < 8; ++n) localNodes[k][n] = local(mesh.hexes[static_cast<std::size_t>(hexes[k])][n]);
        const RegionScore before = scoreHexes(mesh, hexes);
        RegionScore best = before;
        std::vector<Vec3> bestAt = start;
        // Surface node i at p: back within its bound of the surface (its
        // projection), or to where it was if the projection fails.
        auto constrain = [&](std::size_t i, Vec3& p, const Vec3& fallback) {
            const Vec3 q = projector->project(mesh.nodeClass[static_cast<std::size_t>(free[i])].id, p);
            if (!finite(q)) {
                p = fallback;
                return;
            }
            const Vec3 d = p - q;
            const double n = norm(d);
            if (n > bound[i]) p = q + (bound[i] / n) * d;
        };
        std::vector<Vec3> m1(F, Vec3{0, 0, 0}), m2(F, Vec3{0, 0, 0}), grad(F);
        const std::size_t H = hexes.size();
        std::vector<double> w(9 * H), hexLowest(H), hexScore(H);
        std::vector<HexFrames> frames(H);
        std::vector<std::array<Vec3, 8>> hexGrad(H);
        double lr = opt.jointStep * L;
        const double scale = byVolume ? 1.0 / (L * L * L) : 0.0;
        // The per-hex and per-node work of a step runs in parallel; what adds
        // up across hexes (the weights' total, the gradient of a node shared
        // by several hexes) is summed afterwards in the serial order, and
        // minima and counts do not depend on order, so the steps are the
        // serial ones to the last bit for any thread count. (A region has a
        // few hundred hexes and a step takes about a millisecond; one or two
        // regions per mesh are common, so this is where the second core helps.)
        constexpr std::size_t kGrain = 16;
        auto forHexes = [&](auto&& body) {
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H, kGrain), [&](const auto& r) {
                for (std::size_t k = r.begin(); k != r.end(); ++k) body(k);
            });
        };
        for (const double tau : {0.05, 0.02, 0.01, 0.005}) {
            for (int it = 0; it < iterations; ++it) {
                // Soft-min weights over all frames of the region's hexes: the
                // gradient of -tau log sum exp(-s/tau) is the weighted sum of
                // the frames' gradients, weights exp(-s/tau) normalised.
                forHexes([&](std::size_t k) {
                    frameValues(hexCoords(mesh, hexes[k]), frames[k], scale);
                    double m = std::numeric_limits<double>::infinity();
                    for (const FrameState& st : frames[k]) m = std::min(m, st.s);
                    hexLowest[k] = m;
                });
                double lowest = std::numeric_limits<double>::infinity();
                for (std::size_t k = 0; k < H; ++k) lowest = std::min(lowest, hexLowest[k]);
                forHexes([&](std::size_t k) {
                    for (std::size_t f = 0; f < 9; ++f) {
                        // exp(-x) < 1e-12 for x > 27.7 (-ln 1e-12 = 27.63):
                        // weight 0 either way, without the exp.
                        const double x = (frames[k][f].s - lowest) / tau;
                        const double e = x > 27.7 ? 0.0 : std::exp(-x);
                        w[9 * k + f] = e > 1e-12 ? e : 0.0;
                    }
                });
                double total = 0;
                for (std::size_t k = 0; k < 9 * H; ++k) total += w[k];
                forHexes([&](std::size_t k) {
                    for (std::size_t f = 0; f < 9; ++f) w[9 * k + f] /= total;
                    hexGrad[k].fill(Vec3{0, 0, 0});
                    frameGradients(frames[k], &w[9 * k], hexGrad[k], scale);
                });
                std::fill(grad.begin(), grad.end(), Vec3{0, 0, 0});
                for (std::size_t k = 0; k < H; ++k)
                    for (std::size_t n = 0; n < 8; ++n) {
                        const std::ptrdiff_t i = localNodes[k][n];
                        if (i >= 0) grad[static_cast<std::size_t>(i)] = grad[static_cast<std::size_t>(i)] + hexGrad[k][n];
                    }
                tbb::parallel_for(tbb::blocked_range<std::size_t>(0, F, kGrain), [&](const auto& r) {
                    for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        if (pinned[i]) continue;
                        Vec3& x = mesh.nodes[static_cast<std::size_t>(free[i])];
                        const Vec3 old = x;
                        for (std::size_t c = 0; c < 3; ++c) {
                            m1[i][c] = 0.9 * m1[i][c] + 0.1 * grad[i][c];
                            m2[i][c] = 0.999 * m2[i][c] + 0.001 * grad[i][c] * grad[i][c];
                            x[c] += lr * m1[i][c] / (std::sqrt(m2[i][c]) + 1e-12);
                        }
                        if (isSurface[i]) constrain(i, x, old);
                    }
                });
                forHexes([&](std::size_t k) { hexScore[k] = usableScaledJacobian(hexCoords(mesh, hexes[k])); });
                RegionScore now;
                for (std::size_t k = 0; k < H; ++k) {
                    now.inverted += !(hexScore[k] > 0);
                    now.min = std::min(now.min, hexScore[k]);
                }
                if (betterRegion(now, best)) {
                    best = now;
                    for (std::size_t i = 0; i < F; ++i) bestAt[i] = mesh.nodes[static_cast<std::size_t>(free[i])];
                }
            }
            lr *= 0.5;
            // Nothing left for this pass to aim at in the region: stop early.
            if (best.inverted == 0 && best.min >= opt.target) break;
        }
        if (!betterRegion(best, before)) {
            for (std::size_t i = 0; i < F; ++i) mesh.nodes[static_cast<std::size_t>(free[i])] = start[i];
            return false;
        }
        for (std::size_t i = 0; i < F; ++i) mesh.nodes[static_cast<std::size_t>(free[i])] = bestAt[i];
        // Surface nodes back towards the surface: the largest of 1, 1/2, ...
        // 1/64 of the way that keeps the hexes around them at least half as
        // good as the joint move left them (never inverted).
        for (std::size_t i = 0; i < F; ++i) {
            if (!isSurface[i]) continue;
            const Index v = free[i];
            const auto sv = static_cast<std::size_t>(v);
            const Vec3 x = mesh.nodes[sv];
            const Vec3 q = projector->project(mesh.nodeClass[sv].id, x);
            if (!finite(q)) continue;
            const double floor = 0.5 * std::min(minScaledJacobianAround(mesh, topo, v, x), opt.target);
            double t = 1;
            for (int k = 0; k <= 6; ++k, t *= 0.5) {
                const Vec3 p = x + t * (q - x);
                const double m = minScaledJacobianAround(mesh, topo, v, p);
                if (m > 0 && m >= floor) {
                    mesh.nodes[sv] = p;
                    break;
                }
            }
        }
        for (std::size_t i = 0; i < F; ++i) {
            const auto sv = static_cast<std::size_t>(free[i]);
            if (norm(mesh.nodes[sv] - start[i]) > 0) everMoved[sv] = 1;
            if (isSurface[i]) {
                const Vec3 q = projector->project(mesh.nodeClass[sv].id, mesh.nodes[sv]);
                if (!(norm(q - mesh.nodes[sv]) <= 1e-6 * L)) released[sv] = 1;
            }
        }
        for (Index h : hexes) sj[static_cast<std::size_t>(h)] = usableScaledJacobian(hexCoords(mesh, h));
        return true;
    };

    for (int round = 0; round < opt.maxRounds && runRound(false); ++round) {
    }
    if (projector != nullptr && opt.releaseDistance > 0 &&
        std::any_of(sj.begin(), sj.end(), [](double s) { return !(s > 0); }))
        for (int round = 0; round < opt.maxRounds && runRound(true); ++round) {
        }
    // Joint release of what is still inverted (see the comment above
    // FrameTable), one inverted hex at a time in index order, or what is
    // equivalent: regions that share no hex are independent (a region's move
    // reads and writes only its own hexes' nodes), so each batch takes, in
    // index order, the hexes whose region shares no hex with the region of
    // any hex before them still waiting, and runs them in parallel. The result
    // is the serial one for any number of threads.
    if (projector != nullptr && opt.releaseDistance > 0 && opt.jointRings > 0) {
        const auto t0 = std::chrono::steady_clock::now();
        std::atomic<std::size_t> improvedCount{0}, triedCount{0};
        // A joint move is kept when its region gets better, which can leave
        // a neighbour inverted in place of the hex it was for (the region has
        // as many inverted hexes, with a higher minimum): such hexes get
        // their own turn in a further pass.
        std::vector<std::uint8_t> attempted(sj.size(), 0);
        std::vector<std::uint8_t> claimed(sj.size(), 0);
        for (int pass = 0; pass < opt.jointPasses; ++pass) {
            std::vector<std::pair<Index, Region>> pending;
            for (std::size_t h = 0; h < sj.size(); ++h)
                if (!(sj[h] > 0) && !attempted[h]) {
                    attempted[h] = 1;
                    pending.emplace_back(static_cast<Index>(h), regionOf(static_cast<Index>(h), opt.jointRings));
                }
            if (pending.empty()) break;
            while (!pending.empty()) {
                std::vector<std::size_t> batch;
                std::vector<std::pair<Index, Region>> later;
                std::vector<std::size_t> touched;
                for (std::size_t i = 0; i < pending.size(); ++i) {
                    const auto& [h0, region] = pending[i];
                    bool clash = claimed[static_cast<std::size_t>(h0)] != 0;
                    for (Index h : region.hexes) clash = clash || claimed[static_cast<std::size_t>(h)] != 0;
                    if (!clash) batch.push_back(i);
                    for (Index h : region.hexes) {
                        claimed[static_cast<std::size_t>(h)] = 1;
                        touched.push_back(h);
                    }
                    claimed[static_cast<std::size_t>(h0)] = 1;
                    touched.push_back(h0);
                }
                for (Index h : touched) claimed[static_cast<std::size_t>(h)] = 0;
                tbb::parallel_for(tbb::blocked_range<std::size_t>(0, batch.size(), 1), [&](const auto& range) {
                    for (std::size_t b = range.begin(); b != range.end(); ++b) {
                        const auto& [h0, region] = pending[batch[b]];
                        const auto sh = static_cast<std::size_t>(h0);
                        // One joint move of the region if h0 is still inverted
                        // and the move is enabled (iterations > 0).
                        auto attempt = [&](const Region& r, int iterations, bool byVolume) {
                            if (sj[sh] > 0 || iterations <= 0) return;
                            triedCount.fetch_add(1);
                            if (jointRelease(r, iterations, byVolume)) improvedCount.fetch_add(1);
                        };
                        attempt(region, opt.jointIterations, false);
                        // Once more from there with longer stages (the corner of
                        // a plate one cell thick on ch2bet at 1 mm needed it).
                        attempt(region, opt.jointRetryIterations, false);
                        // On the determinants: where the frames around it are
                        // pressed flat the scaled Jacobian's ascent has no
                        // direction (see frameValues).
                        attempt(region, opt.jointVolumeIterations, true);
                        // The same on one ring only, where fewer frames compete
                        // for the soft minimum (a knife-edge gyrus of ch2bet at
                        // 2.5 mm needed it). Its region is part of the wider
                        // one, so the batch stays independent.
                        if (!(sj[sh] > 0) && opt.jointRings > 1) {
                            const Region narrow = regionOf(h0, 1);
                            attempt(narrow, opt.jointRetryIterations, false);
                            attempt(narrow, opt.jointVolumeIterations, true);
                        }
                    }
                });
                std::size_t b = 0;
                for (std::size_t i = 0; i < pending.size(); ++i) {
                    if (b < batch.size() && batch[b] == i) ++b;
                    else later.push_back(std::move(pending[i]));
                }
                pending.swap(later);
            }
        }
        res.jointRegionsImproved = improvedCount.load();
        res.jointRegionsTried = triedCount.load();
        res.jointSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        settledKind = -1;
        const bool improved = res.jointRegionsImproved > 0;
        // The joint move evens out the worst frames of the region; the
        // compass rounds then lift the hexes around it towards the target.
        if (improved)
            for (int round = 0; round < opt.maxRounds && runRound(false); ++round) {
            }
    }
    // The return: surface nodes still off their surface (released here or by the
    // optimiser) go back towards it as far as the hexes around them allow:
    // the largest of 1, 1/2, ... 1/64 of the way to their projection that
    // leaves no hex around them below the smaller of its value and the
    // target, so the minimum cannot fall. One node at a time in index order
    // (few nodes; the same result for any thread count), repeated while a
    // node gets closer, since one node's return can make room for the next.
    // It runs at the very end, and, with a slack, also before the slack
    // rounds: those raise hexes and with them the floors, which would keep
    // nodes released to untangle farther off (ch2bet 2 mm: 7 more nodes
    // beyond 0.1 voxel when it ran only at the end).
    auto returnToSurface = [&](bool last) {
        if (projector == nullptr || opt.returnPasses <= 0) return;
        const auto t0 = std::chrono::steady_clock::now();
        std::vector<double> off(N, 0.0);
        auto distanceOff = [&](std::size_t v) {
            const double d = offBy(v, mesh.nodes[v]);
            return std::isfinite(d) ? d : 0.0;
        };
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, N, 1024), [&](const auto& r) {
            for (std::size_t v = r.begin(); v != r.end(); ++v)
                if (mesh.nodeClass[v].kind == NodeKind::Surface && movable(static_cast<Index>(v)))
                    off[v] = distanceOff(v);
        });
        std::vector<Index> candidates;
        for (std::size_t v = 0; v < N; ++v) {
            if (!(off[v] > 0)) continue;
            const double L = meanEdgeLengthAt(mesh, topo, static_cast<Index>(v));
            if (off[v] > opt.returnTolerance * L) candidates.push_back(static_cast<Index>(v));
        }
        if (last) res.surfaceNodesOffBefore = candidates.size();
        for (int pass = 0; pass < opt.returnPasses && !candidates.empty(); ++pass) {
            bool closer = false;
            for (Index v : candidates) {
                const auto sv = static_cast<std::size_t>(v);
                const Vec3 x = mesh.nodes[sv];
                const Vec3 q = projector->project(mesh.nodeClass[sv].id, x);
                if (!finite(q)) continue;
                const NodeHexes nh(mesh, topo, v);
                const std::vector<double> floors = floorsOf(nh);
                double t = 1;
                for (int k = 0; k <= 6; ++k, t *= 0.5) {
                    const Vec3 p = k == 0 ? q : x + t * (q - x);
                    if (around(nh, p, opt.target, floors.data()).inverted == 0) {
                        mesh.nodes[sv] = p;
                        everMoved[sv] = 1;
                        closer = true;
                        refreshAround(sv);
                        break;
                    }
                }
            }
            std::vector<Index> still;
            for (Index v : candidates) {
                const auto sv = static_cast<std::size_t>(v);
                off[sv] = distanceOff(sv);
                if (off[sv] > opt.returnTolerance * meanEdgeLengthAt(mesh, topo, v)) still.push_back(v);
                else released[sv] = 0;
            }
            candidates.swap(still);
            if (!closer) break;
        }
        // What stays off is marked and counted by the last call only: the
        // rounds in between may still move a node onto its surface (an
        // extraction corner held back, say, which no round released). Off by
        // no more than the slack is within the tolerance the caller set:
        // counted apart, not as released.
        if (last) {
            std::size_t withinSlack = 0;
            for (Index v : candidates) {
                const auto sv = static_cast<std::size_t>(v);
                const bool within = opt.surfaceSlack > 0 && off[sv] <= opt.surfaceSlack;  // (measured just above)
                released[sv] = within ? 0 : 1;
                withinSlack += within;
            }
            res.surfaceNodesWithinSlack = withinSlack;
            res.surfaceNodesOffAfter = candidates.size() - withinSlack;
        }
        res.returnSeconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    };
    // Then the max-min rounds again with surface nodes free in 3-D within
    // surfaceSlack of their surface: on a fold or spur finer than an element
    // the hexes under a surface quad can open only across the surface. After
    // the release and the joint moves, so that what they do with inverted
    // hexes does not depend on the slack (with the slack first, JHU at 5 mm
    // kept 2 inverted hexes the joint release had cleared).
    if (projector != nullptr && opt.surfaceSlack > 0) {
        returnToSurface(false);
        for (int round = 0; round < opt.maxRounds && runRound(false, false, true); ++round) {
        }
    }
    // Last, rounds that raise the mean: the max-min rounds stop once every
    // hex is at the target, and the optimiser's inverse mean ratio is not the
    // scaled Jacobian, so most sheet hexes have room left.
    if (meanRounds) {
        const auto t0 = std::chrono::steady_clock::now();
        double before = 0;
        for (double v : sj) before += v;
        for (int round = 0; round < opt.meanRounds && runRound(false, true); ++round) {
            ++res.meanRounds;
        }
        double after = 0;
        for (double v : sj) after += v;
        res.meanGain = sj.empty() ? 0.0 : (after - before) / static_cast<double>(sj.size());
        res.meanSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    returnToSurface(true);
    res.minAfter = *std::min_element(sj.begin(), sj.end());
    res.belowAfter = countBelow();
    res.nodesMoved = static_cast<std::size_t>(std::count(everMoved.begin(), everMoved.end(), 1));
    res.surfaceNodesReleased = static_cast<std::size_t>(std::count(released.begin(), released.end(), 1));
    return res;
}

}  // namespace isohex::smoothing

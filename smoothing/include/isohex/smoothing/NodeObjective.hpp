#pragma once
// The objective seen by one free node: a corner metric summed over every
// corner of the node's hexes that the node belongs to (as the corner or as
// one of its three neighbours; 4 corners per hex) and the hex's centre frame. Corners the node is not part
// of do not change when it moves, so they are left out.
//
// The corner frames are gathered once per visit into a caller-owned buffer;
// after that, evaluating at a trial displacement touches no mesh memory.
#include <array>
#include <cstddef>
#include <limits>
#include <type_traits>

#include "isohex/core/HexCell.hpp"
#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/CornerMetrics.hpp"
#include "isohex/smoothing/ImrKernel.hpp"

namespace isohex::smoothing {

struct CornerTerm {
    Matrix3 A;  // the corner's Jacobian at the node's current (base) position
    int role;   // 0..2: the node is column `role`; kCornerRole: the node is the corner
    NormDet st; // filled by NodeObjective::derivatives for metrics of NormDet form
};

namespace detail {
struct LocalCorner {
    int corner, role;
};
// For each local node of the reference hex, the four corners it belongs to.
constexpr std::array<std::array<LocalCorner, 4>, 8> makeNodeCorners() {
    std::array<std::array<LocalCorner, 4>, 8> t{};
    for (int v = 0; v < 8; ++v) {
        int n = 0;
        t[v][n++] = {v, kCornerRole};
        for (int k = 0; k < 8; ++k)
            for (int j = 0; j < 3; ++j)
                if (hexcell::kCornerNeighbours[k][j] == v) t[v][n++] = {k, j};
    }
    return t;
}
inline constexpr auto kNodeCorners = makeNodeCorners();
}  // namespace detail

// Reference coordinates (0 or 1 per axis) of the VTK hex's local nodes.
inline constexpr int kReferenceBit[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                            {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

// Upper bound on the terms gatherCornerTerms writes for a node in `hexCount`
// hexes: its 4 corner frames and the hex's centre frame.
inline constexpr std::size_t termsPerHex = 5;

// Writes the corner terms of node v into `out` (room for termsPerHex x the
// node's hex count) and returns how many were written. The node must occur
// once in each of its hexes.
inline std::size_t gatherCornerTerms(const HexMesh& mesh, const Csr& nodeHexes, Index v, CornerTerm* out) {
    std::size_t n = 0;
    for (const Index* h = nodeHexes.begin(static_cast<std::size_t>(v)); h != nodeHexes.end(static_cast<std::size_t>(v)); ++h) {
        const Hex& hex = mesh.hexes[static_cast<std::size_t>(*h)];
        int local = 0;
        while (local < 8 && hex[local] != v) ++local;
        if (local == 8) continue;
        Vector3 x[8];
        for (int i = 0; i < 8; ++i) {
            const Vec3& p = mesh.nodes[static_cast<std::size_t>(hex[i])];
            x[i] = Vector3(p[0], p[1], p[2]);
        }
        for (const detail::LocalCorner& lc : detail::kNodeCorners[local]) {
            const auto& nb = hexcell::kCornerNeighbours[lc.corner];
            CornerTerm& t = out[n++];
            for (int j = 0; j < 3; ++j) t.A.col(j) = x[nb[j]] - x[lc.corner];
            t.role = lc.role;
        }
        // The centre frame: mean edge along each axis (edges 4k..4k+3 of
        // hexcell::kEdges run along axis k from reference 0 to reference 1).
        CornerTerm& c = out[n++];
        for (int k = 0; k < 3; ++k) {
            Vector3 sum = Vector3::Zero();
            for (int e = 4 * k; e < 4 * k + 4; ++e) sum += x[hexcell::kEdges[e][1]] - x[hexcell::kEdges[e][0]];
            c.A.col(k) = 0.25 * sum;
        }
        int bits = 0;
        for (int k = 0; k < 3; ++k) bits |= kReferenceBit[local][k] << k;
        c.role = kCentreRole + bits;
    }
    return n;
}

// Mean length of the edges leaving the node: the length scale for step sizes
// and tolerances (mesh units differ: millimetres, voxels, metres).
inline double localEdgeLength(const CornerTerm* terms, std::size_t count) {
    double sum = 0;
    int edges = 0;
    for (std::size_t i = 0; i < count; ++i)
        if (terms[i].role == kCornerRole) {
            sum += terms[i].A.col(0).norm() + terms[i].A.col(1).norm() + terms[i].A.col(2).norm();
            edges += 3;
        }
    return edges ? sum / edges : 0.0;
}

template <class Metric>
class NodeObjective {
public:
    NodeObjective(const Metric& metric, CornerTerm* terms, std::size_t count)
        : metric_(metric), terms_(terms), count_(count) {}

    std::size_t size() const { return count_; }

    // The objective with the node displaced by d from its base position; +inf
    // if any corner is infeasible for a barrier metric. After derivatives(),
    // metrics of NormDet form are evaluated from the stored n, t and their
    // exact expansions in d, without touching the frames.
    double value(const Vector3& d) const {
        if constexpr (kBatched) {
            if (stateValid_ && batched_) return detail::imrValue(batch_, count_, d);
            if (!stateValid_) return detail::imrFrameValue(terms_, count_, d);
        }
        double sum = 0;
        for (std::size_t i = 0; i < count_; ++i) {
            double v;
            if constexpr (Metric::kNormDetForm) {
                if (stateValid_) {
                    const NormDet& st = terms_[i].st;
                    v = metric_.fromNormDet(st.n + st.gradN.dot(d) + st.w2 * d.squaredNorm(), st.t + st.gradT.dot(d));
                } else {
                    Matrix3 A = terms_[i].A;
                    displaceFrame(A, terms_[i].role, d);
                    v = metric_.value(A);
                }
            } else {
                Matrix3 A = terms_[i].A;
                displaceFrame(A, terms_[i].role, d);
                v = metric_.value(A);
            }
            if constexpr (Metric::kBarrier)
                if (v == std::numeric_limits<double>::infinity()) return v;
            sum += v;
        }
        return sum;
    }

    // Value, gradient and Hessian at the base position; value +inf (and the
    // derivatives meaningless) if a barrier corner is infeasible.
    double derivatives(Vector3& g, Matrix3& H) {
        if constexpr (kBatched) {
            batched_ = count_ <= detail::ImrState::kCapacity;
            if (batched_) {
                const double f = detail::imrDerivatives(terms_, count_, batch_, g, H);
                stateValid_ = f != std::numeric_limits<double>::infinity();
                return f;
            }
        }
        double sum = 0;
        g.setZero();
        H.setZero();
        CornerDerivatives cd;
        for (std::size_t i = 0; i < count_; ++i) {
            bool ok;
            if constexpr (Metric::kNormDetForm) {
                terms_[i].st = normDet(terms_[i].A, terms_[i].role);
                ok = metric_.derivativesFromState(terms_[i].st, cd);
            } else {
                ok = metric_.nodeDerivatives(terms_[i].A, terms_[i].role, cd);
            }
            if (!ok) {
                stateValid_ = false;
                return std::numeric_limits<double>::infinity();
            }
            sum += cd.value;
            g += cd.gradient;
            H += cd.hessian;
        }
        stateValid_ = Metric::kNormDetForm;
        return sum;
    }

    // Moves the base position by d (the node was moved).
    void shift(const Vector3& d) {
        for (std::size_t i = 0; i < count_; ++i) displaceFrame(terms_[i].A, terms_[i].role, d);
        stateValid_ = false;
    }

    // Smallest corner determinant with the node displaced by d.
    double minDeterminant(const Vector3& d) const {
        double m = std::numeric_limits<double>::infinity();
        for (std::size_t i = 0; i < count_; ++i) {
            Matrix3 A = terms_[i].A;
            displaceFrame(A, terms_[i].role, d);
            const double t = cornerDeterminant(A);
            if (t < m) m = t;
        }
        return m;
    }

private:
    // The inverse mean ratio goes through ImrKernel's four-lane kernels (same
    // bits as the loops here), which keep n, t and their gradients in batch_
    // instead of terms_[i].st; nodes with more terms than it holds use the
    // loops.
    static constexpr bool kBatched = std::is_same_v<Metric, InverseMeanRatio>;
    struct NoBatch {};

    Metric metric_;
    CornerTerm* terms_;
    std::size_t count_;
    bool stateValid_ = false;  // the NormDet state describes the current base position
    bool batched_ = false;     // ... and it is in batch_, not in terms_[i].st
    [[no_unique_address]] std::conditional_t<kBatched, detail::ImrState, NoBatch> batch_;
};

// Restricts an objective to the plane through the node's base position with
// unit normal n: the optimiser's steps then have no normal component. The
// normal direction gets a positive curvature so Newton's system stays
// solvable; its gradient there is zero, so no step goes along it.
template <class Objective>
class TangentPlaneObjective {
public:
    TangentPlaneObjective(Objective& inner, const Vector3& normal)
        : inner_(inner), n_(normal), P_(Matrix3::Identity() - normal * normal.transpose()) {}

    double value(const Vector3& d) const { return inner_.value(P_ * d); }
    double derivatives(Vector3& g, Matrix3& H) {
        const double f = inner_.derivatives(g, H);
        g = P_ * g;
        H = P_ * H * P_;
        H += (H.diagonal().cwiseAbs().maxCoeff() + 1e-300) * (n_ * n_.transpose());
        return f;
    }
    void shift(const Vector3& d) { inner_.shift(P_ * d); }

private:
    Objective& inner_;
    Vector3 n_;
    Matrix3 P_;
};

// The same restricted to the line through the node's base position along the
// unit vector t (a curve node's tangent); the other two directions get a
// positive curvature and no gradient.
template <class Objective>
class TangentLineObjective {
public:
    TangentLineObjective(Objective& inner, const Vector3& t) : inner_(inner), P_(t * t.transpose()) {}

    double value(const Vector3& d) const { return inner_.value(P_ * d); }
    double derivatives(Vector3& g, Matrix3& H) {
        const double f = inner_.derivatives(g, H);
        g = P_ * g;
        H = P_ * H * P_;
        H += (H.diagonal().cwiseAbs().maxCoeff() + 1e-300) * (Matrix3::Identity() - P_);
        return f;
    }
    void shift(const Vector3& d) { inner_.shift(P_ * d); }

private:
    Objective& inner_;
    Matrix3 P_;
};

}  // namespace isohex::smoothing

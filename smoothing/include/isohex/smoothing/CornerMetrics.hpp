#pragma once
// Per-corner quality metrics of a hex and their derivatives with respect to
// one node of the corner.
//
// A corner k of a hex has the Jacobian A = [x_a - x_k, x_b - x_k, x_c - x_k]
// (columns; a, b, c = hexcell::kCornerNeighbours[k]). A node takes one of four
// roles in that frame: column 0, 1 or 2 (it is neighbour a, b or c) or the
// corner itself. Moving the node by d changes A by d w^T with w = e_role for a
// neighbour and w = -(1,1,1) for the corner, so every derivative here is taken
// with respect to d along that rank-one change. Because det(A + d w^T) is
// affine in d, the derivatives stay short and exact.
//
// A metric is a small value type with
//   double value(const Matrix3& A) const;                    // +inf where undefined
//   bool nodeDerivatives(const Matrix3& A, int role, CornerDerivatives&) const;
//   static constexpr bool kBarrier;      // true: +inf for det(A) <= 0
//   static constexpr bool kNormDetForm;  // see NormDet below
// NodeObjective sums a metric over a node's corners; the optimiser only sees
// the objective, so a new metric touches neither.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace isohex::smoothing {

using Vector3 = Eigen::Vector3d;
using Matrix3 = Eigen::Matrix3d;

inline constexpr int kCornerRole = 3;  // the node is the corner itself (roles 0..2: a column)
// Roles kCentreRole + bits: the frame is the hex's centre Jacobian (columns:
// the mean of the four edges along xi, eta, zeta), which a node enters with
// w = (s0, s1, s2) / 4, s_k = +1 if bit k is set (the node is at reference
// coordinate 1 along axis k) and -1 otherwise. Verdict and validate() count a
// hex whose centre determinant is <= 0 as inverted even when all 8 corners are
// positive, so the smoother must see it too.
inline constexpr int kCentreRole = 4;

inline Vector3 centreWeights(int role) {
    const int b = role - kCentreRole;
    return Vector3((b & 1) ? 0.25 : -0.25, (b & 2) ? 0.25 : -0.25, (b & 4) ? 0.25 : -0.25);
}

// det(A) as a.(b x c) with a, b, c the columns.
inline double cornerDeterminant(const Matrix3& A) { return A.col(0).dot(A.col(1).cross(A.col(2))); }

// The determinant of A and the derivative of det(A + d w^T) with respect to
// d, cof(A) w, in one go, reusing the cross product both need.
inline void frameDeterminant(const Matrix3& A, int role, Vector3& gradient, double& det) {
    switch (role) {
        case 0: gradient = A.col(1).cross(A.col(2)); det = A.col(0).dot(gradient); return;
        case 1: gradient = A.col(2).cross(A.col(0)); det = A.col(1).dot(gradient); return;
        case 2: gradient = A.col(0).cross(A.col(1)); det = A.col(2).dot(gradient); return;
        case kCornerRole: {
            const Vector3 bc = A.col(1).cross(A.col(2));
            det = A.col(0).dot(bc);
            gradient = -(bc + A.col(2).cross(A.col(0)) + A.col(0).cross(A.col(1)));
            return;
        }
        default: {
            const Vector3 w = centreWeights(role);
            const Vector3 bc = A.col(1).cross(A.col(2));
            det = A.col(0).dot(bc);
            gradient = w[0] * bc + w[1] * A.col(2).cross(A.col(0)) + w[2] * A.col(0).cross(A.col(1));
        }
    }
}

// t^(-1/3) for t > 0. The optimiser needs t^(-2/3) (and 1/t) for every corner
// term, and libm's cbrt plus a division were a third of the run time; this is
// an initial guess from the exponent bits refined by four multiply-only
// Newton steps (relative error about 1e-15 for t in [1e-18, 1e18]; libm
// outside that range).
inline double inverseCubeRoot(double t) {
    if (!(t > 1e-18 && t < 1e18)) return 1.0 / std::cbrt(t);
    std::int64_t bits;
    std::memcpy(&bits, &t, sizeof bits);
    bits = 0x553ef0ff289dd796LL - bits / 3;
    double y;
    std::memcpy(&y, &bits, sizeof y);
    for (int k = 0; k < 4; ++k) y = y * (4.0 - t * y * y * y) * (1.0 / 3.0);
    return y;
}

inline double inversePowTwoThirds(double t) {
    const double y = inverseCubeRoot(t);
    return y * y;
}

// A w.
inline Vector3 roleTimes(const Matrix3& A, int role) {
    if (role < kCornerRole) return A.col(role);
    if (role == kCornerRole) return -(A.col(0) + A.col(1) + A.col(2));
    return A * centreWeights(role);
}

// |w|^2.
inline double roleNorm2(int role) { return role < kCornerRole ? 1.0 : role == kCornerRole ? 3.0 : 3.0 / 16.0; }

// A += d w^T: the frame after the node moved by d.
inline void displaceFrame(Matrix3& A, int role, const Vector3& d) {
    if (role < kCornerRole) A.col(role) += d;
    else if (role == kCornerRole) A.colwise() -= d;
    else A += d * centreWeights(role).transpose();
}

struct CornerDerivatives {
    double value = 0;
    Vector3 gradient = Vector3::Zero();
    Matrix3 hessian = Matrix3::Zero();
};

// What both metrics here depend on: n = |A|_F^2 and t = det(A), with their
// gradients along the node's move (grad n = 2 A w; grad t = cof(A) w; hess n
// = 2 |w|^2 I; hess t = 0). Moving the node by d changes them exactly to
// n + gradN.d + |w|^2 |d|^2 and t + gradT.d, which NodeObjective uses to make
// line-search evaluations cheap. A metric with
//   static constexpr bool kNormDetForm = true;
//   double fromNormDet(double n, double t) const;
//   bool derivativesFromState(const NormDet&, CornerDerivatives&) const;
// gets that fast path; any other metric only needs value/nodeDerivatives.
struct NormDet {
    double n = 0, t = 0;
    Vector3 gradN = Vector3::Zero(), gradT = Vector3::Zero();
    double w2 = 1;  // |w|^2
};

inline NormDet normDet(const Matrix3& A, int role) {
    NormDet s;
    frameDeterminant(A, role, s.gradT, s.t);
    s.n = A.squaredNorm();
    s.gradN = 2.0 * roleTimes(A, role);
    s.w2 = roleNorm2(role);
    return s;
}

// Knupp's inverse mean ratio |A|_F^2 / (3 det(A)^(2/3)): 1 for a right-angled
// corner with equal edges, growing without bound as the corner flattens.
// +inf (a barrier) when det(A) <= 0, so a line search that rejects +inf can
// never invert a corner.
struct InverseMeanRatio {
    static constexpr bool kBarrier = true;
    static constexpr bool kNormDetForm = true;

    double fromNormDet(double n, double t) const {
        if (!(t > 0)) return std::numeric_limits<double>::infinity();
        return n * inversePowTwoThirds(t) * (1.0 / 3.0);
    }

    double value(const Matrix3& A) const { return fromNormDet(A.squaredNorm(), cornerDeterminant(A)); }

    // With c = grad t and gn = grad n:
    //   f = n t^(-2/3) / 3
    //   grad f = t^(-2/3)/3 [gn - (2/3)(n/t) c]
    //   hess f = t^(-2/3)/3 [2|w|^2 I - (2/3)/t (gn c^T + c gn^T) + (10/9)(n/t^2) c c^T]
    bool derivativesFromState(const NormDet& st, CornerDerivatives& out) const {
        const double t = st.t, n = st.n;
        if (!(t > 0)) {
            out.value = std::numeric_limits<double>::infinity();
            return false;
        }
        const Vector3& gn = st.gradN;
        const Vector3& c = st.gradT;
        const double y = inverseCubeRoot(t);
        const double s = y * y * (1.0 / 3.0);  // t^(-2/3) / 3
        const double invT = y * y * y;         // 1/t to within rounding
        out.value = n * s;
        out.gradient = s * (gn - (2.0 / 3.0) * n * invT * c);
        const double a = (2.0 / 3.0) * invT, b = (10.0 / 9.0) * n * invT * invT;
        for (int i = 0; i < 3; ++i)
            for (int j = i; j < 3; ++j) {
                const double h =
                    s * (b * c[i] * c[j] - a * (gn[i] * c[j] + c[i] * gn[j]) + (i == j ? 2.0 * st.w2 : 0.0));
                out.hessian(i, j) = h;
                out.hessian(j, i) = h;
            }
        return true;
    }

    bool nodeDerivatives(const Matrix3& A, int role, CornerDerivatives& out) const {
        return derivativesFromState(normDet(A, role), out);
    }
};

// Knupp's untangling measure |t| - t with t = det(A) - beta, i.e. 2 max(0,
// beta - det): zero once the corner is at least beta positive, growing
// linearly with how far it is inverted. Its kink at det = beta is rounded off
// over a width `smoothing` (value s + sqrt(s^2 + smoothing^2) with s = beta - det;
// smoothing = 0 is exactly Knupp's measure) so that Newton steps apply; the
// objective stays convex in one node's position because det is affine in it.
struct UntangleBeta {
    static constexpr bool kBarrier = false;
    static constexpr bool kNormDetForm = true;
    double beta = 0;
    double smoothing = 0;

    double fromNormDet(double, double t) const {
        const double s = beta - t;
        return s + std::sqrt(s * s + smoothing * smoothing);
    }

    double value(const Matrix3& A) const { return fromNormDet(0.0, cornerDeterminant(A)); }

    bool derivativesFromState(const NormDet& st, CornerDerivatives& out) const {
        const Vector3& c = st.gradT;
        const double s = beta - st.t;
        const double r = std::sqrt(s * s + smoothing * smoothing);
        out.value = s + r;
        if (r > 0) {
            out.gradient = -(1.0 + s / r) * c;
            out.hessian = (smoothing * smoothing / (r * r * r)) * (c * c.transpose());
        } else {  // s = 0 with no smoothing: take the one-sided slope of the kink
            out.gradient = -c;
            out.hessian.setZero();
        }
        return true;
    }

    bool nodeDerivatives(const Matrix3& A, int role, CornerDerivatives& out) const {
        return derivativesFromState(normDet(A, role), out);
    }
};

}  // namespace isohex::smoothing

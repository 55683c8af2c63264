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
//   static constexpr bool kBarrier;  // true: +inf for det(A) <= 0
// NodeObjective sums a metric over a node's corners; the optimiser only sees
// the objective, so a new metric touches neither.
#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace isohex::smoothing {

using Vector3 = Eigen::Vector3d;
using Matrix3 = Eigen::Matrix3d;

inline constexpr int kCornerRole = 3;  // the node is the corner itself (roles 0..2: a column)

// det(A) as a.(b x c) with a, b, c the columns.
inline double cornerDeterminant(const Matrix3& A) { return A.col(0).dot(A.col(1).cross(A.col(2))); }

// The derivative of det(A + d w^T) with respect to d: cof(A) w.
inline Vector3 determinantGradient(const Matrix3& A, int role) {
    const Vector3 bc = A.col(1).cross(A.col(2));
    const Vector3 ca = A.col(2).cross(A.col(0));
    const Vector3 ab = A.col(0).cross(A.col(1));
    switch (role) {
        case 0: return bc;
        case 1: return ca;
        case 2: return ab;
        default: return -(bc + ca + ab);
    }
}

// The determinant of A and its gradient cof(A) w in one go, reusing the cross
// product both need.
inline void frameDeterminant(const Matrix3& A, int role, Vector3& gradient, double& det) {
    switch (role) {
        case 0: gradient = A.col(1).cross(A.col(2)); det = A.col(0).dot(gradient); return;
        case 1: gradient = A.col(2).cross(A.col(0)); det = A.col(1).dot(gradient); return;
        case 2: gradient = A.col(0).cross(A.col(1)); det = A.col(2).dot(gradient); return;
        default: {
            const Vector3 bc = A.col(1).cross(A.col(2));
            det = A.col(0).dot(bc);
            gradient = -(bc + A.col(2).cross(A.col(0)) + A.col(0).cross(A.col(1)));
        }
    }
}

// A w.
inline Vector3 roleTimes(const Matrix3& A, int role) {
    return role < kCornerRole ? Vector3(A.col(role)) : Vector3(-(A.col(0) + A.col(1) + A.col(2)));
}

// |w|^2.
inline double roleNorm2(int role) { return role < kCornerRole ? 1.0 : 3.0; }

// A += d w^T: the frame after the node moved by d.
inline void displaceFrame(Matrix3& A, int role, const Vector3& d) {
    if (role < kCornerRole) A.col(role) += d;
    else A.colwise() -= d;
}

struct CornerDerivatives {
    double value = 0;
    Vector3 gradient = Vector3::Zero();
    Matrix3 hessian = Matrix3::Zero();
};

// Knupp's inverse mean ratio |A|_F^2 / (3 det(A)^(2/3)): 1 for a right-angled
// corner with equal edges, growing without bound as the corner flattens.
// +inf (a barrier) when det(A) <= 0, so a line search that rejects +inf can
// never invert a corner.
struct InverseMeanRatio {
    static constexpr bool kBarrier = true;

    double value(const Matrix3& A) const {
        const double t = cornerDeterminant(A);
        if (!(t > 0)) return std::numeric_limits<double>::infinity();
        return A.squaredNorm() / (3.0 * std::cbrt(t * t));
    }

    // With n = |A|_F^2 (quadratic in d) and t = det (affine in d, gradient c):
    //   f = n t^(-2/3) / 3
    //   grad f = t^(-2/3)/3 [grad n - (2/3)(n/t) c]
    //   hess f = t^(-2/3)/3 [hess n - (2/3)/t (grad n c^T + c grad n^T) + (10/9)(n/t^2) c c^T]
    // where grad n = 2 A w and hess n = 2 |w|^2 I.
    bool nodeDerivatives(const Matrix3& A, int role, CornerDerivatives& out) const {
        Vector3 c;
        double t;
        frameDeterminant(A, role, c, t);
        if (!(t > 0)) {
            out.value = std::numeric_limits<double>::infinity();
            return false;
        }
        const double n = A.squaredNorm();
        const Vector3 gn = 2.0 * roleTimes(A, role);
        const double s = 1.0 / (3.0 * std::cbrt(t * t));  // t^(-2/3) / 3
        const double invT = 1.0 / t;
        out.value = n * s;
        const double k = (2.0 / 3.0) * n * invT;
        out.gradient = s * (gn - k * c);
        // s [2|w|^2 I - (2/3)/t (gn c^T + c gn^T) + (10/9) n/t^2 c c^T], entry by entry:
        const double a = (2.0 / 3.0) * invT, b = (10.0 / 9.0) * n * invT * invT;
        for (int i = 0; i < 3; ++i)
            for (int j = i; j < 3; ++j) {
                const double h = s * (b * c[i] * c[j] - a * (gn[i] * c[j] + c[i] * gn[j]) +
                                      (i == j ? 2.0 * roleNorm2(role) : 0.0));
                out.hessian(i, j) = h;
                out.hessian(j, i) = h;
            }
        return true;
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
    double beta = 0;
    double smoothing = 0;

    double value(const Matrix3& A) const {
        const double s = beta - cornerDeterminant(A);
        return s + std::sqrt(s * s + smoothing * smoothing);
    }

    bool nodeDerivatives(const Matrix3& A, int role, CornerDerivatives& out) const {
        Vector3 c;
        double t;
        frameDeterminant(A, role, c, t);
        const double s = beta - t;
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
};

}  // namespace isohex::smoothing

#include "isohex/pipeline/FieldProjector.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

namespace isohex::pipeline {

namespace {

Vec3 notProjected() {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    return {nan, nan, nan};
}

// The smoother only asks for points near the surface (a node moved a
// fraction of an element along it), so a projection that has to travel
// more than a few voxels has found the wrong place, typically where the
// field is flat far from any surface. Answer with a non-finite point: the
// smoother rejects such a move (otherwise an untangling step could carry a
// surface node far off the surface).
Vec3 nearby(const imaging::ImplicitField& f, const Vec3& x) {
    imaging::ProjectOptions o;
    o.maxDistanceVoxels = 3.0;
    const imaging::Projection p = f.projectDetailed(x, o);
    if (p.converged) return p.point;
    return notProjected();
}

// Newton steps on F (value and gradient) along its gradient, each at most
// half a voxel, keeping the best point; NaN beyond 3 voxels (see nearby()).
template <class Fn>
Vec3 newtonOnto(const Fn& F, const Vec3& x0, double voxel) {
    const double maxStep = 0.5 * voxel;
    Vec3 x = x0, best = x0;
    double bestAbs = std::numeric_limits<double>::infinity(), bestGrad = 0;
    for (int it = 0; it < 30; ++it) {
        Vec3 g;
        const double f = F(x, g);
        const double g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
        if (std::abs(f) < bestAbs) {
            bestAbs = std::abs(f);
            bestGrad = std::sqrt(g2);
            best = x;
        }
        if (!(g2 > 0)) break;
        double step = f / std::sqrt(g2);
        if (std::abs(step) < 1e-6 * voxel) break;
        step = std::clamp(step, -maxStep, maxStep);
        const double inv = 1.0 / std::sqrt(g2);
        for (int c = 0; c < 3; ++c) x[c] -= step * g[c] * inv;
    }
    const double moved = std::sqrt((best[0] - x0[0]) * (best[0] - x0[0]) + (best[1] - x0[1]) * (best[1] - x0[1]) +
                                   (best[2] - x0[2]) * (best[2] - x0[2]));
    // Off the zero set (first-order distance |F|/|grad F| above 1e-3
    // voxel): Newton stopped where F is flat, or ran out of steps.
    if (moved > 3.0 * voxel || !(bestAbs <= 1e-3 * voxel * bestGrad)) return notProjected();
    return best;
}

// Levenberg-Marquardt onto the common zero set of two functions (F gives
// both values and their gradients as the rows of J): damped least-norm
// steps, which also get through places where one function is flat and the
// two gradients agree, each step at most half a voxel; NaN where it does not
// end within 1e-3 voxels of both or more than 3 voxels away.
template <class Fn>
Vec3 levenbergMarquardtOnto(const Fn& F, const Vec3& x0, double voxel) {
    Eigen::Vector3d x(x0[0], x0[1], x0[2]);
    Eigen::Matrix<double, 2, 3> J;
    Eigen::Vector2d f;
    bool settled = false;
    for (int it = 0; it < 40 && !settled; ++it) {
        f = F(Vec3{x[0], x[1], x[2]}, J);
        if (!f.allFinite() || !J.allFinite()) return notProjected();
        Eigen::Matrix2d JJ = J * J.transpose();
        const double damping = 1e-6 * JJ.trace() + 1e-300;
        JJ.diagonal().array() += damping;
        Eigen::Vector3d step = J.transpose() * JJ.ldlt().solve(f);
        if (!step.allFinite()) return notProjected();
        settled = step.norm() < 1e-6 * voxel;
        if (step.norm() > 0.5 * voxel) step *= 0.5 * voxel / step.norm();
        x -= step;
    }
    f = F(Vec3{x[0], x[1], x[2]}, J);
    for (int i = 0; i < 2; ++i)
        if (!(std::abs(f[i]) <= 1e-3 * voxel * J.row(i).norm())) return notProjected();
    if ((x - Eigen::Vector3d(x0[0], x0[1], x0[2])).norm() > 3.0 * voxel) return notProjected();
    return {x[0], x[1], x[2]};
}

}  // namespace

Vec3 FieldProjector::project(std::int32_t surfaceId, const Vec3& x) const {
    const SurfaceTag& s = surfaces_.at(static_cast<std::size_t>(surfaceId));
    const std::int32_t a = s.inside, b = s.outside;
    if (repaired_ && (a > 0 || b > 0) && repaired_->nearChange(x)) return projectRepaired(a, b, x);
    if (a > 0 && b <= 0) return nearby(domain_.field(a), x);
    if (a <= 0 && b > 0) return nearby(domain_.field(b), x);
    if (a <= 0 && b <= 0) return x;  // the box around a meshed exterior: stays put
    return projectDifference(a, b, x);
}

bool FieldProjector::projectsOnto(std::int32_t surfaceId) const {
    const SurfaceTag& s = surfaces_.at(static_cast<std::size_t>(surfaceId));
    return s.inside > 0 || s.outside > 0;
}

// Near a grid point the repair changed: onto the repaired field's zero set
// (of f_a, of f_b, or of f_a - f_b), the surface the mesh was extracted on.
Vec3 FieldProjector::projectRepaired(std::int32_t a, std::int32_t b, const Vec3& x) const {
    const octree::Domain& r = *repaired_;
    return newtonOnto(
        [&](const Vec3& y, Vec3& g) {
            Vec3 ga{0, 0, 0}, gb{0, 0, 0};
            double f = 0;
            if (a > 0) f += r.value(a, y, &ga);
            if (b > 0) f -= r.value(b, y, &gb);
            g = {ga[0] - gb[0], ga[1] - gb[1], ga[2] - gb[2]};
            return f;
        },
        x, domain_.field(a > 0 ? a : b).voxelSize());
}

// Newton steps on F = f_a - f_b along its gradient, each at most half a
// voxel, keeping the best point; enough for the small moves of smoothing.
Vec3 FieldProjector::projectDifference(std::int32_t a, std::int32_t b, const Vec3& x0) const {
    const imaging::ImplicitField& fa = domain_.field(a);
    const imaging::ImplicitField& fb = domain_.field(b);
    return newtonOnto(
        [&](const Vec3& y, Vec3& g) {
            Vec3 ga, gb;
            const double F = fa.valueAndGradient(y, ga) - fb.valueAndGradient(y, gb);
            g = {ga[0] - gb[0], ga[1] - gb[1], ga[2] - gb[2]};
            return F;
        },
        x0, fa.voxelSize());
}

Vec3 FieldProjector::projectToCurve(std::int32_t curveId, const Vec3& x0) const {
    if (curveId < 0 || static_cast<std::size_t>(curveId) >= curves_.size()) return notProjected();
    const auto [p, q, r] = curves_[static_cast<std::size_t>(curveId)];
    const bool outer = p <= 0;
    const imaging::ImplicitField& fq = domain_.field(q);
    const imaging::ImplicitField& fr = domain_.field(r);
    // the two functions whose common zero set is the curve, with gradients
    auto F = [&](const Vec3& y, Eigen::Matrix<double, 2, 3>& J) {
        Vec3 gq, gr, g0;
        const double vq = fq.valueAndGradient(y, gq), vr = fr.valueAndGradient(y, gr);
        double v0;
        if (outer) {
            v0 = domain_.unionValue(y, &g0);
        } else {
            v0 = domain_.field(p).valueAndGradient(y, g0);
            v0 -= vq;
            g0 = {g0[0] - gq[0], g0[1] - gq[1], g0[2] - gq[2]};
        }
        for (int c = 0; c < 3; ++c) {
            J(0, c) = gq[c] - gr[c];
            J(1, c) = g0[c];
        }
        return Eigen::Vector2d(vq - vr, v0);
    };
    return levenbergMarquardtOnto(F, x0, fq.voxelSize());
}

}  // namespace isohex::pipeline

#pragma once
// How one node moves: damped Newton steps on a NodeObjective with a
// backtracking Armijo line search. The line search only accepts finite
// values, so with a barrier metric (InverseMeanRatio) no corner determinant
// can become non-positive. Works with any type offering the NodeObjective
// interface (value, derivatives, shift).
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#include "isohex/smoothing/CornerMetrics.hpp"

namespace isohex::smoothing {

struct NewtonOptions {
    // Newton steps per visit (a Gauss-Seidel sweep revisits anyway). Most
    // visits end sooner on minStep, so a third step adds little per visit
    // and saves sweeps: 5-22% fewer node moves than with 2 on the bench
    // inputs (bench/RESULTS.md).
    int maxIterations = 3;
    double armijo = 1e-4;       // sufficient decrease: f(x + a p) <= f(x) + armijo a g.p
    int maxHalvings = 30;       // backtracking steps before giving up on a direction
    double maxStep = 0.5;       // longest step, in units of the local edge length
    double minStep = 1e-2;      // no further iteration after a step shorter than this (edge lengths)
};

struct NodeMove {
    Vector3 displacement = Vector3::Zero();  // total move of the node
    double before = 0;                       // objective at the start
    double after = 0;                        // objective at the end (== before if not moved)
    int steps = 0;                           // accepted steps
};

// Minimises `objective` over the node's displacement, starting at zero.
// `length` is the local edge length; iterations stop once |gradient| <=
// gradientTolerance. The objective is left shifted to the final position.
template <class Objective>
NodeMove newtonDescent(Objective& objective, double length, double gradientTolerance, const NewtonOptions& opt) {
    NodeMove move;
    Vector3 g;
    Matrix3 H;
    double f = objective.derivatives(g, H);
    move.before = move.after = f;
    if (!std::isfinite(f) || !(length > 0)) return move;
    const double maxStep = opt.maxStep * length;
    for (int it = 0; it < opt.maxIterations; ++it) {
        if (!(g.norm() > gradientTolerance)) break;
        // Newton direction; where the Hessian is not positive definite (the
        // metric is not convex everywhere) shift its spectrum until it is.
        Vector3 p;
        {
            Eigen::LLT<Matrix3> llt(H);
            if (llt.info() == Eigen::Success) {
                p = -llt.solve(g);
            } else {
                const double scale = H.diagonal().cwiseAbs().maxCoeff() + g.norm() / maxStep;
                double mu = 1e-3 * scale;
                bool ok = false;
                for (int k = 0; k < 12 && !ok; ++k, mu *= 10) {
                    Eigen::LLT<Matrix3> damped(H + mu * Matrix3::Identity());
                    if (damped.info() == Eigen::Success) {
                        p = -damped.solve(g);
                        ok = true;
                    }
                }
                if (!ok) p = -g;
            }
            if (!p.allFinite() || !(p.dot(g) < 0)) p = -g;
            const double len = p.norm();
            if (len > maxStep) p *= maxStep / len;
        }
        const double slope = g.dot(p);
        double alpha = 1.0, ft = std::numeric_limits<double>::infinity();
        bool accepted = false;
        for (int h = 0; h <= opt.maxHalvings; ++h, alpha *= 0.5) {
            ft = objective.value(alpha * p);
            if (std::isfinite(ft) && ft <= f + opt.armijo * alpha * slope) {
                accepted = true;
                break;
            }
        }
        if (!accepted) break;
        const Vector3 step = alpha * p;
        objective.shift(step);
        move.displacement += step;
        move.after = ft;
        ++move.steps;
        if (!(it + 1 < opt.maxIterations && step.norm() > opt.minStep * length)) break;
        f = objective.derivatives(g, H);
        if (!std::isfinite(f)) break;  // cannot happen for a feasible step; be safe
    }
    return move;
}

}  // namespace isohex::smoothing

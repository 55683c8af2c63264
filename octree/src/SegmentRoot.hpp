#pragma once
// The root of a function on a segment whose ends it brackets (private to
// octree/: dual contouring's Hermite data, the adaptive mesher's surface nets).
#include <algorithm>
#include <cmath>

#include "isohex/core/HexMesh.hpp"

namespace isohex::octree {

// Root of F on the segment p..q given F(p) = f0 < 0 < F(q) = f1 (or the other
// way round): Illinois false position, superlinear and never leaving the
// bracket. Returns the parameter t in [0, 1].
template <class Fn>
inline double rootOnSegment(const Fn& F, const Vec3& p, const Vec3& q, double f0, double f1) {
    const double sign = f0 > 0 ? -1.0 : 1.0;  // orient so that f0 < 0 < f1
    f0 *= sign;
    f1 *= sign;
    const Vec3 d{q[0] - p[0], q[1] - p[1], q[2] - p[2]};
    // |F| this small is the surface to about 1e-8 of the segment's length
    const double ftol = 1e-8 * std::max(-f0, f1);
    double t0 = 0, t1 = 1, t = 0.5;
    int side = 0;
    for (int it = 0; it < 40; ++it) {
        t = (t0 * f1 - t1 * f0) / (f1 - f0);
        const Vec3 x{p[0] + t * d[0], p[1] + t * d[1], p[2] + t * d[2]};
        const double f = sign * F(x);
        if (std::abs(t1 - t0) < 1e-9 || std::abs(f) <= ftol) break;
        if (f < 0) {
            t0 = t;
            f0 = f;
            if (side == -1) f1 *= 0.5;
            side = -1;
        } else {
            t1 = t;
            f1 = f;
            if (side == 1) f0 *= 0.5;
            side = 1;
        }
    }
    return t;
}

}  // namespace isohex::octree

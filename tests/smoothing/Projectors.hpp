#pragma once
// Analytic SurfaceProjectors for the smoothing tests.
#include <cmath>

#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::test {

// Every surface is the sphere |x - centre| = radius.
struct SphereProjector final : smoothing::SurfaceProjector {
    Vec3 centre{0, 0, 0};
    double radius = 1;
    SphereProjector(Vec3 c, double r) : centre(c), radius(r) {}
    Vec3 project(std::int32_t, const Vec3& x) const override {
        const double d[3] = {x[0] - centre[0], x[1] - centre[1], x[2] - centre[2]};
        const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (!(n > 0)) return x;
        return {centre[0] + radius * d[0] / n, centre[1] + radius * d[1] / n, centre[2] + radius * d[2] / n};
    }
    double distance(const Vec3& x) const {
        return std::abs(std::hypot(x[0] - centre[0], x[1] - centre[1], x[2] - centre[2]) - radius);
    }
};

// Every surface is the plane n.x = offset (n of unit length).
struct PlaneProjector final : smoothing::SurfaceProjector {
    Vec3 normal{0, 0, 1};
    double offset = 0;
    PlaneProjector(Vec3 n, double o) : normal(n), offset(o) {}
    Vec3 project(std::int32_t, const Vec3& x) const override {
        const double s = x[0] * normal[0] + x[1] * normal[1] + x[2] * normal[2] - offset;
        return {x[0] - s * normal[0], x[1] - s * normal[1], x[2] - s * normal[2]};
    }
};

}  // namespace isohex::test

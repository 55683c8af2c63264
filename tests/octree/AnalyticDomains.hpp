#pragma once
// Analytic solids for octree tests: signed distance functions (negative inside).
#include <algorithm>
#include <cmath>
#include <functional>
#include <utility>
#include <vector>

#include "isohex/octree/Domain.hpp"
#include "isohex/octree/Grid.hpp"

namespace isohex::test {

using Sdf = std::function<double(const Vec3&)>;

// Gradient of f at x by central differences.
template <class F>
Vec3 centralGradient(const F& f, const Vec3& x) {
    const double h = 1e-6;
    Vec3 g{};
    for (int a = 0; a < 3; ++a) {
        Vec3 p = x, q = x;
        p[a] += h;
        q[a] -= h;
        g[a] = (f(p) - f(q)) / (2 * h);
    }
    return g;
}

inline Sdf sphere(Vec3 c, double r) {
    return [=](const Vec3& x) {
        return std::sqrt((x[0] - c[0]) * (x[0] - c[0]) + (x[1] - c[1]) * (x[1] - c[1]) + (x[2] - c[2]) * (x[2] - c[2])) - r;
    };
}
inline Sdf torus(Vec3 c, double big, double small) {
    return [=](const Vec3& x) {
        const double dx = x[0] - c[0], dy = x[1] - c[1], dz = x[2] - c[2];
        const double q = std::sqrt(dx * dx + dy * dy) - big;
        return std::sqrt(q * q + dz * dz) - small;
    };
}
inline Sdf box(Vec3 lo, Vec3 hi) {
    return [=](const Vec3& x) {
        double out = 0, in = -1e300;
        for (int a = 0; a < 3; ++a) {
            const double d = std::max(lo[a] - x[a], x[a] - hi[a]);
            out += d > 0 ? d * d : 0;
            in = std::max(in, d);
        }
        return out > 0 ? std::sqrt(out) : in;
    };
}
// A box with edges and corners rounded to radius r.
inline Sdf roundedBox(Vec3 lo, Vec3 hi, double r) {
    const Sdf inner = box({lo[0] + r, lo[1] + r, lo[2] + r}, {hi[0] - r, hi[1] - r, hi[2] - r});
    return [=](const Vec3& x) { return inner(x) - r; };
}
inline Sdf unite(Sdf a, Sdf b) {
    return [=](const Vec3& x) { return std::min(a(x), b(x)); };
}

// Materials 1..n, each an SDF; a point belongs to the first material whose SDF
// is negative (most negative wins where they overlap).
class AnalyticDomain : public octree::Domain {
public:
    // `unionOf`: the solid all materials make up together; by default the
    // smallest of their distances.
    explicit AnalyticDomain(std::vector<Sdf> materials, Sdf unionOf = {})
        : m_(std::move(materials)), union_(std::move(unionOf)) {}
    std::int32_t materialAt(const Vec3& x) const override {
        std::int32_t best = 0;
        double bestValue = 0;
        for (std::size_t i = 0; i < m_.size(); ++i) {
            const double v = m_[i](x);
            if (v < bestValue) {
                bestValue = v;
                best = static_cast<std::int32_t>(i + 1);
            }
        }
        return best;
    }
    double value(std::int32_t material, const Vec3& x, Vec3* g) const override {
        const Sdf& f = m_.at(static_cast<std::size_t>(material - 1));
        const double v = f(x);
        if (g) *g = centralGradient(f, x);
        return v;
    }
    // The union of the materials: the smallest of their distances.
    double unionValue(const Vec3& x, Vec3* g) const override {
        auto f = [&](const Vec3& y) {
            if (union_) return union_(y);
            double v = 1e300;
            for (const Sdf& s : m_) v = std::min(v, s(y));
            return v;
        };
        if (g) *g = centralGradient(f, x);
        return f(x);
    }

private:
    std::vector<Sdf> m_;
    Sdf union_;
};

// A labelled point set given directly (for hand-made non-manifold cases):
// material at the nearest grid point of a unit grid at the origin.
class PointSetDomain : public octree::Domain {
public:
    PointSetDomain(std::array<int, 3> dims, std::vector<std::int32_t> labels) : dims_(dims), labels_(std::move(labels)) {}
    std::int32_t materialAt(const Vec3& x) const override {
        const int i = static_cast<int>(std::lround(x[0])), j = static_cast<int>(std::lround(x[1])),
                  k = static_cast<int>(std::lround(x[2]));
        if (i < 0 || j < 0 || k < 0 || i >= dims_[0] || j >= dims_[1] || k >= dims_[2]) return 0;
        return labels_[(static_cast<std::size_t>(k) * dims_[1] + j) * dims_[0] + i];
    }
    double value(std::int32_t material, const Vec3& x, Vec3* g) const override {
        // distance-like: -0.5 at points of the material, +0.5 elsewhere, blended trilinearly
        if (g) *g = {0, 0, 0};
        const double v = materialAt(x) == material ? -0.5 : 0.5;
        return v;
    }

private:
    std::array<int, 3> dims_;
    std::vector<std::int32_t> labels_;
};

inline octree::Grid unitGrid(int n, double h = 1.0, Vec3 origin = {0, 0, 0}) {
    octree::Grid g;
    g.origin = origin;
    g.axes = {{{h, 0, 0}, {0, h, 0}, {0, 0, h}}};
    g.dims = {n, n, n};
    return g;
}

}  // namespace isohex::test

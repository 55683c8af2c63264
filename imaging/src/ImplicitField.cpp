#include "isohex/imaging/ImplicitField.hpp"

#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <optional>
#include <limits>

#include <openvdb/tools/Interpolation.h>

#include "isohex/core/Error.hpp"

namespace isohex::imaging {
namespace {

// Read-only accessor that is not registered with the tree: constructing one is
// a few stores, so each query may own one and no accessor is ever shared.
using ConstAccessor = openvdb::tree::ValueAccessor<const openvdb::FloatTree, /*IsSafe=*/false>;

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// Every field gets an id that no other field ever gets; copies share it (and
// the grid, which never changes). Each thread keeps accessors for the last few
// fields it sampled, so consecutive queries reuse the accessor's cached path
// to the leaf instead of descending from the root every time. An entry of a
// field that no longer exists is never looked up again (its id is not reused).
std::atomic<std::uint64_t> gNextFieldId{1};

struct AccessorCache {
    static constexpr int kSlots = 4;
    std::array<std::uint64_t, kSlots> id{};
    std::array<std::optional<ConstAccessor>, kSlots> acc;
    int next = 0;
    ConstAccessor& get(std::uint64_t fieldId, const openvdb::FloatTree& tree) {
        for (int s = 0; s < kSlots; ++s)
            if (id[s] == fieldId) return *acc[s];
        const int s = next;
        next = (next + 1) % kSlots;
        id[s] = fieldId;
        acc[s].emplace(tree);
        return *acc[s];
    }
};
thread_local AccessorCache tAccessors;

}  // namespace

ImplicitField::ImplicitField(openvdb::FloatGrid::ConstPtr grid, Interpolation interpolation)
    : grid_(std::move(grid)), interpolation_(interpolation), id_(gNextFieldId++) {
    if (!grid_) throw Error("ImplicitField: no grid given.");
    const auto& xf = grid_->transform();
    if (!xf.isLinear()) {
        throw Error("ImplicitField: grid '" + grid_->getName() +
                    "' has a non-linear (frustum) transform; resample it to a linear one first.");
    }
    const openvdb::math::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
    for (int w = 0; w < 3; ++w) {
        origin_[w] = m(3, w);
        for (int i = 0; i < 3; ++i) a_[3 * w + i] = m(i, w);
    }
    const double* a = a_;
    const double det = a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
                       a[2] * (a[3] * a[7] - a[4] * a[6]);
    if (!(std::fabs(det) > 0.0)) throw Error("ImplicitField: the grid transform is singular.");
    inv_[0] = (a[4] * a[8] - a[5] * a[7]) / det;
    inv_[1] = (a[2] * a[7] - a[1] * a[8]) / det;
    inv_[2] = (a[1] * a[5] - a[2] * a[4]) / det;
    inv_[3] = (a[5] * a[6] - a[3] * a[8]) / det;
    inv_[4] = (a[0] * a[8] - a[2] * a[6]) / det;
    inv_[5] = (a[2] * a[3] - a[0] * a[5]) / det;
    inv_[6] = (a[3] * a[7] - a[4] * a[6]) / det;
    inv_[7] = (a[1] * a[6] - a[0] * a[7]) / det;
    inv_[8] = (a[0] * a[4] - a[1] * a[3]) / det;
    voxelSize_ = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 3; ++i) {
        const double len = std::sqrt(a[i] * a[i] + a[3 + i] * a[3 + i] + a[6 + i] * a[6 + i]);
        voxelSize_ = std::min(voxelSize_, len);
    }
}

Vec3 ImplicitField::toIndex(const Vec3& x) const {
    const double d[3] = {x[0] - origin_[0], x[1] - origin_[1], x[2] - origin_[2]};
    return {inv_[0] * d[0] + inv_[1] * d[1] + inv_[2] * d[2],
            inv_[3] * d[0] + inv_[4] * d[1] + inv_[5] * d[2],
            inv_[6] * d[0] + inv_[7] * d[1] + inv_[8] * d[2]};
}

double ImplicitField::sampleIndex(const openvdb::Vec3d& p, openvdb::Vec3d* grad) const {
    ConstAccessor& acc = tAccessors.get(id_, grid_->tree());
    if (interpolation_ == Interpolation::Quadratic) {
        auto sample = [&](const openvdb::Vec3d& q) {
            float v = 0.0f;
            openvdb::tools::QuadraticSampler::sample(acc, q, v);
            return double(v);
        };
        if (grad) {
            // OpenVDB's quadratic sampler is piecewise, so differentiate over
            // a quarter voxel rather than analytically.
            constexpr double h = 0.25;
            for (int a = 0; a < 3; ++a) {
                openvdb::Vec3d lo = p, hi = p;
                lo[a] -= h;
                hi[a] += h;
                (*grad)[a] = (sample(hi) - sample(lo)) / (2 * h);
            }
        }
        return sample(p);
    }
    // Trilinear value with its exact gradient inside the cell.
    const openvdb::Coord c(int(std::floor(p[0])), int(std::floor(p[1])), int(std::floor(p[2])));
    const double tx = p[0] - c.x(), ty = p[1] - c.y(), tz = p[2] - c.z();
    double v[2][2][2];
    for (int dz = 0; dz < 2; ++dz)
        for (int dy = 0; dy < 2; ++dy)
            for (int dx = 0; dx < 2; ++dx)
                v[dz][dy][dx] = acc.getValue(c.offsetBy(dx, dy, dz));
    auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
    const double y0z0 = lerp(v[0][0][0], v[0][0][1], tx), y1z0 = lerp(v[0][1][0], v[0][1][1], tx);
    const double y0z1 = lerp(v[1][0][0], v[1][0][1], tx), y1z1 = lerp(v[1][1][0], v[1][1][1], tx);
    const double z0 = lerp(y0z0, y1z0, ty), z1 = lerp(y0z1, y1z1, ty);
    if (grad) {
        const double dx00 = v[0][0][1] - v[0][0][0], dx10 = v[0][1][1] - v[0][1][0];
        const double dx01 = v[1][0][1] - v[1][0][0], dx11 = v[1][1][1] - v[1][1][0];
        (*grad)[0] = lerp(lerp(dx00, dx10, ty), lerp(dx01, dx11, ty), tz);
        (*grad)[1] = lerp(y1z0 - y0z0, y1z1 - y0z1, tz);
        (*grad)[2] = z1 - z0;
    }
    return lerp(z0, z1, tz);
}

double ImplicitField::value(const Vec3& world) const {
    const Vec3 i = toIndex(world);
    return sampleIndex(openvdb::Vec3d(i[0], i[1], i[2]), nullptr);
}

double ImplicitField::valueAndGradient(const Vec3& world, Vec3& g) const {
    const Vec3 i = toIndex(world);
    openvdb::Vec3d gi;
    const double v = sampleIndex(openvdb::Vec3d(i[0], i[1], i[2]), &gi);
    // df/dworld = inv^T * df/dindex, since index = inv * (world - origin).
    for (int w = 0; w < 3; ++w) g[w] = inv_[w] * gi[0] + inv_[3 + w] * gi[1] + inv_[6 + w] * gi[2];
    return v;
}

Vec3 ImplicitField::gradient(const Vec3& world) const {
    Vec3 g;
    valueAndGradient(world, g);
    return g;
}

void ImplicitField::bounds(Vec3& lo, Vec3& hi) const {
    const openvdb::CoordBBox box = grid_->evalActiveVoxelBoundingBox();
    lo = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
          std::numeric_limits<double>::infinity()};
    hi = {-lo[0], -lo[1], -lo[2]};
    for (int corner = 0; corner < 8; ++corner) {
        const double ijk[3] = {double((corner & 1) ? box.max().x() : box.min().x()),
                               double((corner & 2) ? box.max().y() : box.min().y()),
                               double((corner & 4) ? box.max().z() : box.min().z())};
        for (int w = 0; w < 3; ++w) {
            const double x = origin_[w] + a_[3 * w] * ijk[0] + a_[3 * w + 1] * ijk[1] + a_[3 * w + 2] * ijk[2];
            lo[w] = std::min(lo[w], x);
            hi[w] = std::max(hi[w], x);
        }
    }
}

Projection ImplicitField::projectDetailed(const Vec3& start, const ProjectOptions& o) const {
    const double tol = o.toleranceVoxels * voxelSize_;
    const double maxStep = o.maxStepVoxels * voxelSize_;
    const double maxDist = o.maxDistanceVoxels * voxelSize_;
    auto distanceEstimate = [](double f, const Vec3& g) {
        const double n = std::sqrt(dot(g, g));
        return n > 0.0 ? std::fabs(f) / n : std::numeric_limits<double>::infinity();
    };
    auto away = [&](const Vec3& p) {
        const Vec3 d{p[0] - start[0], p[1] - start[1], p[2] - start[2]};
        return std::sqrt(dot(d, d));
    };

    Projection out;
    out.point = start;
    Vec3 x = start, g;
    double f = valueAndGradient(x, g);
    if (f == 0.0 || distanceEstimate(f, g) < tol) {
        out.converged = true;
        return out;
    }
    double bestEstimate = distanceEstimate(f, g);
    for (int it = 0; it < o.maxIterations; ++it) {
        out.iterations = it + 1;
        double g2 = dot(g, g);
        if (!(g2 > 1e-300)) {
            // Flat here (e.g. more than a voxel away from a label boundary):
            // look for a slope over growing distances. The step is then a
            // plain maxStep move down (or up) that slope.
            for (double h = voxelSize_; h <= maxDist && !(g2 > 1e-300); h *= 2) {
                for (int a = 0; a < 3; ++a) {
                    Vec3 lo = x, hi = x;
                    lo[a] -= h;
                    hi[a] += h;
                    g[a] = (value(hi) - value(lo)) / (2 * h);
                }
                g2 = dot(g, g);
            }
            if (!(g2 > 1e-300)) break;  // no direction to the surface anywhere near
            const double scale = std::fabs(f) / (maxStep * std::sqrt(g2));
            g = {g[0] * scale, g[1] * scale, g[2] * scale};  // makes the Newton step maxStep long
            g2 = dot(g, g);
        }
        Vec3 step{-f * g[0] / g2, -f * g[1] / g2, -f * g[2] / g2};
        double len = std::sqrt(dot(step, step));
        if (len > maxStep) {
            for (auto& s : step) s *= maxStep / len;
            len = maxStep;
        }
        const Vec3 y{x[0] + step[0], x[1] + step[1], x[2] + step[2]};
        Vec3 gy;
        const double fy = valueAndGradient(y, gy);

        if ((fy <= 0.0) != (f <= 0.0) || fy == 0.0) {
            // The segment x..y crosses the surface: pin the crossing on it.
            double lo = 0.0, hi = 1.0, flo = f;
            double t = f / (f - fy);  // secant guess
            Vec3 p = y;
            for (int k = 0; k < o.maxIterations; ++k) {
                p = {x[0] + t * step[0], x[1] + t * step[1], x[2] + t * step[2]};
                Vec3 gp;
                const double fp = valueAndGradient(p, gp);
                if (fp == 0.0 || distanceEstimate(fp, gp) < tol || (hi - lo) * len < tol) break;
                if ((fp <= 0.0) == (flo <= 0.0)) {
                    lo = t;
                    flo = fp;
                } else {
                    hi = t;
                }
                const double dfdt = dot(gp, step);
                double tn = dfdt != 0.0 ? t - fp / dfdt : 0.5 * (lo + hi);
                if (!(tn > lo && tn < hi)) tn = 0.5 * (lo + hi);  // Newton left the bracket
                t = tn;
            }
            out.point = p;
            out.converged = true;
            out.distance = away(p);
            return out;
        }
        x = y;
        f = fy;
        g = gy;
        const double est = distanceEstimate(f, g);
        if (est < bestEstimate) {
            bestEstimate = est;
            out.point = x;
        }
        if (est < tol) {
            out.point = x;
            out.converged = true;
            break;
        }
        if (away(x) > maxDist) break;
    }
    out.distance = away(out.point);
    return out;
}

}  // namespace isohex::imaging

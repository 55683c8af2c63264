// The scan's field with a trilinear hat at each grid point whose label the
// repair changed (see RepairedDomain.hpp).
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/RepairedDomain.hpp"

#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

#include "isohex/core/Error.hpp"

namespace isohex::octree {

namespace {

std::uint64_t key(std::size_t point, std::int32_t material) {
    return (static_cast<std::uint64_t>(point) << 32) | static_cast<std::uint32_t>(material);
}

}  // namespace

RepairedDomain::RepairedDomain(const Domain& base, const Labels& sampled, const Labels& repaired)
    : base_(base), grid_(repaired.grid) {
    if (sampled.material.size() != repaired.material.size() || sampled.grid.dims != repaired.grid.dims)
        throw Error("internal: RepairedDomain needs the sampled and repaired labels of one grid");
    const Grid& g = grid_;
    // inverse of the matrix whose columns are the grid axes
    const auto& a = g.axes;
    const double det = g.determinant();
    for (int r = 0; r < 3; ++r) {
        const auto& u = a[(r + 1) % 3];
        const auto& w = a[(r + 2) % 3];
        toGrid_[r] = {(u[1] * w[2] - u[2] * w[1]) / det, (u[2] * w[0] - u[0] * w[2]) / det,
                      (u[0] * w[1] - u[1] * w[0]) / det};
    }
    // the points whose label changed, in grid order (parallel over slabs)
    const auto [nx, ny, nz] = g.dims;
    std::vector<std::vector<std::size_t>> slab(static_cast<std::size_t>(nz));
    tbb::parallel_for(0, nz, [&](int k) {
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t p = g.index(i, j, k);
                if (sampled.material[p] != repaired.material[p]) slab[static_cast<std::size_t>(k)].push_back(p);
            }
    });
    std::vector<std::size_t> points;
    for (const auto& v : slab) points.insert(points.end(), v.begin(), v.end());
    if (points.empty()) return;
    // Hats per point: each material of the point before and after, and the
    // union of all materials where the point left it or joined it.
    struct Hat {
        std::int32_t material = 0;
        double height = 0;
        bool used = false;
    };
    std::vector<std::array<Hat, 3>> hats(points.size());
    tbb::parallel_for(std::size_t{0}, points.size(), [&](std::size_t n) {
        const std::size_t p = points[n];
        const int i = static_cast<int>(p % nx), j = static_cast<int>(p / nx % ny), k = static_cast<int>(p / nx / ny);
        const std::int32_t was = sampled.material[p], now = repaired.material[p];
        const Vec3 x = g.point(i, j, k);
        int slot = 0;
        for (const std::int32_t m : {now, was, kUnion}) {
            if (m == 0 || (m == kUnion && (was != 0) == (now != 0))) continue;
            const bool wantInside = m == kUnion ? now != 0 : m == now;
            const double f = at(m, x, nullptr);
            if (!std::isfinite(f) || (f < 0) == wantInside) continue;
            // the field's step to the grid neighbours, for a point that sits on the iso value
            double step = 0;
            int count = 0;
            for (int d = 0; d < 3; ++d)
                for (int s = -1; s <= 1; s += 2) {
                    int q[3] = {i, j, k};
                    q[d] += s;
                    if (q[d] < 0 || q[d] >= g.dims[d]) continue;
                    step += std::abs(at(m, g.point(q[0], q[1], q[2]), nullptr) - f);
                    ++count;
                }
            const double size = std::max({std::abs(f), count ? 0.1 * step / count : 0.0, 1e-12});
            hats[n][slot++] = {m, (wantInside ? -size : size) - f, true};
        }
    });
    changed_.assign(g.size(), 0);
    hatCell_.assign(g.size(), 0);
    for (std::size_t n = 0; n < points.size(); ++n) {
        const std::size_t p = points[n];
        bool any = false;
        for (const Hat& h : hats[n])
            if (h.used) {
                hat_[key(p, h.material)] = h.height;
                any = true;
            }
        if (!any) continue;
        changed_[p] = 1;
        ++changedCount_;
        // the 8 cells around p (each indexed by its lowest grid point)
        const int i = static_cast<int>(p % nx), j = static_cast<int>(p / nx % ny), k = static_cast<int>(p / nx / ny);
        for (int c = 0; c < 8; ++c) {
            const int ci = i - (c & 1), cj = j - (c >> 1 & 1), ck = k - (c >> 2 & 1);
            if (ci >= 0 && cj >= 0 && ck >= 0) hatCell_[g.index(ci, cj, ck)] = 1;
        }
    }
}

bool RepairedDomain::cellHasHat(int i0, int j0, int k0) const {
    if (i0 < 0 || j0 < 0 || k0 < 0 || i0 >= grid_.dims[0] || j0 >= grid_.dims[1] || k0 >= grid_.dims[2]) return false;
    return hatCell_[grid_.index(i0, j0, k0)] != 0;
}

std::array<double, 3> RepairedDomain::gridCoords(const Vec3& x) const {
    const Vec3 d{x[0] - grid_.origin[0], x[1] - grid_.origin[1], x[2] - grid_.origin[2]};
    std::array<double, 3> u;
    for (int r = 0; r < 3; ++r) u[r] = toGrid_[r][0] * d[0] + toGrid_[r][1] * d[1] + toGrid_[r][2] * d[2];
    return u;
}

bool RepairedDomain::nearChange(const Vec3& x) const {
    if (changedCount_ == 0) return false;
    const auto u = gridCoords(x);
    return cellHasHat(static_cast<int>(std::floor(u[0])), static_cast<int>(std::floor(u[1])),
                      static_cast<int>(std::floor(u[2])));
}

double RepairedDomain::at(std::int32_t material, const Vec3& x, Vec3* gradient) const {
    return material == kUnion ? base_.unionValue(x, gradient) : base_.value(material, x, gradient);
}

double RepairedDomain::value(std::int32_t material, const Vec3& x, Vec3* gradient) const {
    return withHats(material, x, gradient);
}

double RepairedDomain::unionValue(const Vec3& x, Vec3* gradient) const { return withHats(kUnion, x, gradient); }

double RepairedDomain::withHats(std::int32_t material, const Vec3& x, Vec3* gradient) const {
    double f = at(material, x, gradient);
    if (changedCount_ == 0 || !std::isfinite(f)) return f;
    const auto u = gridCoords(x);
    const int i0 = static_cast<int>(std::floor(u[0])), j0 = static_cast<int>(std::floor(u[1])),
              k0 = static_cast<int>(std::floor(u[2]));
    if (!cellHasHat(i0, j0, k0)) return f;
    std::array<double, 3> gu{0, 0, 0};
    for (int c = 0; c < 8; ++c) {
        const int o[3] = {c & 1, c >> 1 & 1, c >> 2 & 1};
        const int i = i0 + o[0], j = j0 + o[1], k = k0 + o[2];
        if (i < 0 || j < 0 || k < 0 || i >= grid_.dims[0] || j >= grid_.dims[1] || k >= grid_.dims[2]) continue;
        const std::size_t p = grid_.index(i, j, k);
        if (!changed_[p]) continue;
        const auto it = hat_.find(key(p, material));
        if (it == hat_.end()) continue;
        // trilinear weight of grid point (i, j, k) at u, and its derivatives
        double w[3], dw[3];
        const int q[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
            const double t = u[a] - q[a];  // in [-1, 1]
            w[a] = 1.0 - std::abs(t);
            dw[a] = o[a] ? 1.0 : -1.0;     // d(1 - |t|)/du: t < 0 for the upper corner
        }
        f += it->second * w[0] * w[1] * w[2];
        gu[0] += it->second * dw[0] * w[1] * w[2];
        gu[1] += it->second * w[0] * dw[1] * w[2];
        gu[2] += it->second * w[0] * w[1] * dw[2];
    }
    if (gradient)
        for (int c = 0; c < 3; ++c)
            (*gradient)[c] += toGrid_[0][c] * gu[0] + toGrid_[1][c] * gu[1] + toGrid_[2][c] * gu[2];
    return f;
}

}  // namespace isohex::octree

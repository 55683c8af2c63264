#include "isohex/pipeline/LocalFeatures.hpp"

#include <algorithm>
#include <map>
#include <set>

#include <Eigen/Dense>

namespace isohex::pipeline {

const char* shapeText(LocalShape shape) {
    switch (shape) {
        case LocalShape::Speck: return "speck";
        case LocalShape::Pocket: return "pocket";
        case LocalShape::Strand: return "strand one element wide";
        case LocalShape::Tunnel: return "tunnel one element wide";
        case LocalShape::ThinSheet: return "sheet or gap one element thick";
        case LocalShape::RepairSite: return "non-manifold repair site";
        case LocalShape::TripleLine: return "label triple line";
        case LocalShape::Boundary: return "smooth boundary";
        case LocalShape::Interior: return "interior";
    }
    return "interior";
}

namespace {

constexpr int kWindow = 4;  // the radius (grid points) a small component must stay within
constexpr std::array<std::array<int, 3>, 6> kSix{{{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}}};

}  // namespace

LocalFeatures::LocalFeatures(const octree::Labels& labels, const octree::RepairedDomain* repaired)
    : labels_(labels), repaired_(repaired) {
    Eigen::Matrix3d axes;
    for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) axes(c, a) = labels.grid.axes[a][c];
    const Eigen::Matrix3d inv = axes.inverse();
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) toGrid_[r][c] = inv(r, c);
    cellVolume_ = std::abs(axes.determinant());
}

std::array<int, 3> LocalFeatures::nearestPoint(const Vec3& x) const {
    const Vec3& o = labels_.grid.origin;
    std::array<int, 3> g{};
    for (int r = 0; r < 3; ++r) {
        double v = 0;
        for (int c = 0; c < 3; ++c) v += toGrid_[r][c] * (x[c] - o[c]);
        g[r] = static_cast<int>(std::lround(v));
    }
    return g;
}

int LocalFeatures::thinAxes(int i, int j, int k) const {
    const std::int32_t m = labels_.at(i, j, k);
    int n = 0;
    for (int a = 0; a < 3; ++a) {
        const std::array<int, 3> d{a == 0, a == 1, a == 2};
        if (labels_.at(i + d[0], j + d[1], k + d[2]) != m && labels_.at(i - d[0], j - d[1], k - d[2]) != m) ++n;
    }
    return n;
}

std::vector<std::size_t> LocalFeatures::flood(std::size_t p, const std::array<int, 3>& centre, int radius,
                                              bool thinOnly) const {
    const octree::Grid& g = labels_.grid;
    const std::int32_t m = labels_.material[p];
    std::vector<std::size_t> comp{p}, stack{p};
    std::set<std::size_t> seen{p};
    while (!stack.empty()) {
        const auto [i, j, k] = g.coords(stack.back());
        stack.pop_back();
        for (const auto& d : kSix) {
            const int a = i + d[0], b = j + d[1], c = k + d[2];
            if (!g.contains(a, b, c)) return {};  // the grid's border: not enclosed
            const std::size_t q = g.index(a, b, c);
            if (labels_.material[q] != m || seen.count(q) || (thinOnly && thinAxes(a, b, c) < 2)) continue;
            if (std::abs(a - centre[0]) > radius || std::abs(b - centre[1]) > radius || std::abs(c - centre[2]) > radius)
                return {};
            seen.insert(q);
            comp.push_back(q);
            stack.push_back(q);
            if (comp.size() > kFeaturePoints) return {};
        }
    }
    std::sort(comp.begin(), comp.end());
    return comp;
}

LocalShape LocalFeatures::shapeAt(const Vec3& centre) const {
    const octree::Grid& g = labels_.grid;
    const std::array<int, 3> c = nearestPoint(centre);
    std::set<std::int32_t> labels;
    int thinMost = 0;
    bool thinBackground = false;
    bool small = false, smallBackground = false;
    for (int dk = -1; dk <= 1; ++dk)
        for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
                const int i = c[0] + di, j = c[1] + dj, k = c[2] + dk;
                const std::int32_t m = labels_.at(i, j, k);
                labels.insert(m);
                if (!g.contains(i, j, k)) continue;
                if (!flood(g.index(i, j, k), c, kWindow, false).empty()) {
                    small = true;
                    smallBackground = smallBackground || m == 0;
                }
                const int t = thinAxes(i, j, k);
                if (t > thinMost || (t == thinMost && t >= 2 && m == 0)) thinBackground = m == 0;
                thinMost = std::max(thinMost, t);
            }
    if (small) return smallBackground ? LocalShape::Pocket : LocalShape::Speck;
    if (thinMost >= 2) return thinBackground ? LocalShape::Tunnel : LocalShape::Strand;
    if (thinMost == 1) return LocalShape::ThinSheet;
    if (repaired_)
        for (int n = 0; n < 8; ++n) {
            const Vec3 x = g.point(c[0] + ((n & 1) ? 0.5 : -0.5), c[1] + ((n & 2) ? 0.5 : -0.5),
                                   c[2] + ((n & 4) ? 0.5 : -0.5));
            if (repaired_->nearChange(x)) return LocalShape::RepairSite;
        }
    if (labels.size() >= 3) return LocalShape::TripleLine;
    return labels.size() == 2 ? LocalShape::Boundary : LocalShape::Interior;
}

FineFeature LocalFeatures::describe(LocalShape shape, std::vector<std::size_t> points) const {
    const octree::Grid& g = labels_.grid;
    FineFeature f;
    f.shape = shape;
    f.material = labels_.material[points.front()];
    std::map<std::int32_t, int> around;
    Vec3 sum{0, 0, 0};
    const std::set<std::size_t> in(points.begin(), points.end());
    for (std::size_t p : points) {
        const auto [i, j, k] = g.coords(p);
        const Vec3 x = g.point(i, j, k);
        for (int c = 0; c < 3; ++c) sum[c] += x[c];
        for (const auto& d : kSix) {
            const int a = i + d[0], b = j + d[1], cc = k + d[2];
            const std::int32_t m = labels_.at(a, b, cc);
            if (m != f.material) ++around[m];
        }
    }
    // the most common label around it, the smallest id on a tie (deterministic)
    int best = -1;
    for (const auto& [m, n] : around)
        if (n > best) {
            best = n;
            f.replacedBy = m;
        }
    const double n = static_cast<double>(points.size());
    f.at = {sum[0] / n, sum[1] / n, sum[2] / n};
    f.volume = n * cellVolume_;
    f.points = std::move(points);
    return f;
}

std::vector<FineFeature> LocalFeatures::featuresAt(const Vec3& centre) const {
    const octree::Grid& g = labels_.grid;
    const std::array<int, 3> c = nearestPoint(centre);
    std::vector<FineFeature> out;
    std::set<std::size_t> taken;
    for (int dk = -1; dk <= 1; ++dk)
        for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
                const int i = c[0] + di, j = c[1] + dj, k = c[2] + dk;
                if (!g.contains(i, j, k)) continue;
                const std::size_t p = g.index(i, j, k);
                if (taken.count(p)) continue;
                const bool background = labels_.material[p] == 0;
                std::vector<std::size_t> comp = flood(p, c, kWindow, false);
                LocalShape shape = background ? LocalShape::Pocket : LocalShape::Speck;
                if (comp.empty() && thinAxes(i, j, k) >= 2) {
                    comp = flood(p, c, kWindow, true);
                    shape = background ? LocalShape::Tunnel : LocalShape::Strand;
                }
                if (comp.empty()) continue;
                taken.insert(comp.begin(), comp.end());
                out.push_back(describe(shape, std::move(comp)));
            }
    return out;
}

}  // namespace isohex::pipeline

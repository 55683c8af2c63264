#include "isohex/octree/RequestMasks.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "isohex/core/Error.hpp"

namespace isohex::octree {

std::array<int, 3> levelDims(const std::array<int, 3>& points, int level) {
    int step = 1;
    for (int l = 0; l < level; ++l) step *= 3;
    std::array<int, 3> d;
    for (int c = 0; c < 3; ++c) d[c] = std::max(1, (points[c] + step - 1) / step);
    return d;
}

RequestMasks emptyRequests(const std::array<int, 3>& points, int top) {
    RequestMasks m(static_cast<std::size_t>(top) + 1);
    for (int l = 1; l <= top; ++l) {
        const auto d = levelDims(points, l);
        m[static_cast<std::size_t>(l)].assign(static_cast<std::size_t>(d[0]) * d[1] * d[2], 0);
    }
    return m;
}

void orRequests(RequestMasks& into, const RequestMasks& from) {
    if (into.size() < from.size()) into.resize(from.size());
    for (std::size_t l = 0; l < from.size(); ++l) {
        if (from[l].empty()) continue;
        auto& to = into[l];
        if (to.empty()) to.assign(from[l].size(), 0);
        if (to.size() != from[l].size()) throw Error("internal error: refinement requests of two sizes for one level");
        for (std::size_t c = 0; c < to.size(); ++c) to[c] = static_cast<std::uint8_t>(to[c] | from[l][c]);
    }
}

std::size_t countRequests(const RequestMasks& masks) {
    std::size_t n = 0;
    for (const auto& m : masks) n += static_cast<std::size_t>(std::count_if(m.begin(), m.end(), [](std::uint8_t v) { return v != 0; }));
    return n;
}

void dilateCells(std::vector<std::uint8_t>& mask, const std::array<int, 3>& dims, int rings) {
    if (rings <= 0) return;
    const std::array<std::size_t, 3> stride{1, static_cast<std::size_t>(dims[0]),
                                            static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(dims[1])};
    std::vector<std::uint8_t> before;
    for (int axis = 0; axis < 3; ++axis) {
        before = mask;
        const int n = dims[axis];
        for (std::size_t c = 0; c < mask.size(); ++c) {
            if (!before[c]) continue;
            const int at = static_cast<int>(c / stride[axis] % static_cast<std::size_t>(n));
            const std::size_t first = c - static_cast<std::size_t>(at) * stride[axis];
            for (int t = std::max(0, at - rings); t <= std::min(n - 1, at + rings); ++t)
                mask[first + static_cast<std::size_t>(t) * stride[axis]] = 1;
        }
    }
}

std::vector<std::uint8_t> requestsAround(const std::vector<Vec3>& at, const Grid& grid, int rings) {
    const auto dims = levelDims(grid.dims, 1);
    std::vector<std::uint8_t> mask(static_cast<std::size_t>(dims[0]) * dims[1] * dims[2], 0);
    Eigen::Matrix3d axes;
    for (int c = 0; c < 3; ++c) axes.col(c) = Eigen::Vector3d(grid.axes[c][0], grid.axes[c][1], grid.axes[c][2]);
    const Eigen::Matrix3d toGrid = axes.inverse();
    for (const Vec3& x : at) {
        const Eigen::Vector3d u =
            toGrid * Eigen::Vector3d(x[0] - grid.origin[0], x[1] - grid.origin[1], x[2] - grid.origin[2]);
        std::array<int, 3> p;
        for (int c = 0; c < 3; ++c) p[c] = static_cast<int>(std::lround(u[c]));
        if (!grid.contains(p[0], p[1], p[2])) continue;
        mask[(static_cast<std::size_t>(p[2] / 3) * dims[1] + static_cast<std::size_t>(p[1] / 3)) * dims[0] +
             static_cast<std::size_t>(p[0] / 3)] = 1;
    }
    dilateCells(mask, dims, rings);
    return mask;
}

}  // namespace isohex::octree

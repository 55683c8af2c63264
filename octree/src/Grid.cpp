// The sampling grid's geometry.
#include <cmath>

#include "isohex/octree/Grid.hpp"

namespace isohex::octree {

std::array<double, 3> Grid::spacing() const {
    std::array<double, 3> s;
    for (int a = 0; a < 3; ++a)
        s[a] = std::sqrt(axes[a][0] * axes[a][0] + axes[a][1] * axes[a][1] + axes[a][2] * axes[a][2]);
    return s;
}

double Grid::determinant() const {
    const auto& a = axes[0];
    const auto& b = axes[1];
    const auto& c = axes[2];
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

Grid coarsen(const Grid& base, int level) {
    Grid g = base;
    const int s = 1 << level;
    for (int a = 0; a < 3; ++a) {
        for (int c = 0; c < 3; ++c) g.axes[a][c] = base.axes[a][c] * s;
        g.dims[a] = (base.dims[a] - 1 + s - 1) / s + 1;
    }
    return g;
}

}  // namespace isohex::octree

#include "isohex/pipeline/GridPositions.hpp"

#include <Eigen/Dense>

#include "isohex/core/Quality.hpp"

namespace isohex::pipeline {

std::vector<std::array<double, 3>> hexCentresInGrid(const HexMesh& mesh, const octree::Grid& grid,
                                                    const std::vector<Index>& hexes) {
    Eigen::Matrix3d axes;
    for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) axes(c, a) = grid.axes[a][c];
    const Eigen::Matrix3d toGrid = axes.inverse();
    const Vec3& o = grid.origin;
    std::vector<std::array<double, 3>> at;
    at.reserve(hexes.size());
    for (Index h : hexes) {
        const Vec3 c = hexCentre(mesh, h);
        const Eigen::Vector3d x = toGrid * Eigen::Vector3d(c[0] - o[0], c[1] - o[1], c[2] - o[2]);
        at.push_back({x[0], x[1], x[2]});
    }
    return at;
}

}  // namespace isohex::pipeline

#pragma once
// The sampling grid: a regular lattice of points in world space, and its
// geometry (spacing, handedness, coarser grids over the same box).
#include <array>
#include <cstddef>

#include "isohex/core/HexMesh.hpp"

namespace isohex::octree {

// A regular grid of sample points: point (i,j,k) sits at
// origin + i*axes[0] + j*axes[1] + k*axes[2], 0 <= i < dims[0] etc. The axes
// may be anisotropic and oblique (the scan's direction cosines times the
// element size). Points are numbered x fastest (index).
struct Grid {
    Vec3 origin{0, 0, 0};
    std::array<Vec3, 3> axes{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
    std::array<int, 3> dims{0, 0, 0};

    Vec3 point(double i, double j, double k) const {
        Vec3 p = origin;
        for (int c = 0; c < 3; ++c) p[c] += i * axes[0][c] + j * axes[1][c] + k * axes[2][c];
        return p;
    }
    std::size_t size() const {
        return static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(dims[1]) * static_cast<std::size_t>(dims[2]);
    }
    std::size_t index(int i, int j, int k) const {
        return (static_cast<std::size_t>(k) * dims[1] + j) * dims[0] + i;
    }
    // Grid coordinates (i, j, k) of point index p (the inverse of index).
    std::array<int, 3> coords(std::size_t p) const {
        const auto nx = static_cast<std::size_t>(dims[0]), ny = static_cast<std::size_t>(dims[1]);
        return {static_cast<int>(p % nx), static_cast<int>(p / nx % ny), static_cast<int>(p / nx / ny)};
    }
    // Whether (i, j, k) is a point of the grid.
    bool contains(int i, int j, int k) const {
        return i >= 0 && j >= 0 && k >= 0 && i < dims[0] && j < dims[1] && k < dims[2];
    }
    // Length of the grid step along each axis, world units.
    std::array<double, 3> spacing() const;
    // Determinant of the axes: negative for a mirrored (left-handed) grid.
    double determinant() const;
};

// The grid `level` steps coarser than `base` over the same box (same origin):
// axes 2^level times as long, and enough points to cover base's last point.
Grid coarsen(const Grid& base, int level);

}  // namespace isohex::octree

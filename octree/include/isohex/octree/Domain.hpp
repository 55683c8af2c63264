#pragma once
// What the mesher needs to know about the solid: which material a point is
// in, and a signed function per material (negative inside) with its gradient
// for Hermite data. The pipeline implements this over the scan's OpenVDB
// fields; tests implement it analytically. Must be safe to call from many
// threads at once.
#include <array>
#include <cstdint>
#include <limits>

#include "isohex/core/HexMesh.hpp"

namespace isohex::octree {

class Domain {
public:
    virtual ~Domain() = default;
    // Material at x; 0 = background (outside every selected material).
    virtual std::int32_t materialAt(const Vec3& x) const = 0;
    // Signed function of one material (< 0 inside it), world units or intensity
    // units; only its zero set and the direction of its gradient matter.
    virtual double value(std::int32_t material, const Vec3& x, Vec3* gradient = nullptr) const = 0;
    // Signed function of the union of all materials (< 0 inside any of them),
    // with its gradient: the outer boundary where two or more materials meet
    // it (label maps: the surface of the labelled region as a whole, which the
    // materials' own surfaces leave gaps in). NaN when not known: such
    // vertices then stay at their QEF point.
    virtual double unionValue(const Vec3& x, Vec3* gradient = nullptr) const {
        (void)x;
        (void)gradient;
        return std::numeric_limits<double>::quiet_NaN();
    }
    // The domain to ask about points of the extraction grid's cell holding x
    // (x its centre): one that changes the field only near some grid points
    // answers with the domain underneath elsewhere, so the many queries of a
    // cell skip its bookkeeping. Default: this domain.
    virtual const Domain& within(const Vec3& x) const {
        (void)x;
        return *this;
    }
    // The material x would belong to if it were not in `material` (for
    // non-manifold repair that removes a point from a region). Default: 0.
    virtual std::int32_t materialOtherThan(std::int32_t material, const Vec3& x) const {
        (void)material;
        (void)x;
        return 0;
    }
};

// A regular grid of sample points: point (i,j,k) sits at
// origin + i*axes[0] + j*axes[1] + k*axes[2], 0 <= i < dims[0] etc. The axes
// may be anisotropic and oblique (the scan's direction cosines times the
// element size).
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
    // Length of the grid step along each axis, world units.
    std::array<double, 3> spacing() const;
    // Determinant of the axes: negative for a mirrored (left-handed) grid.
    double determinant() const;
};

}  // namespace isohex::octree

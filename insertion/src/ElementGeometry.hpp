#pragma once
// Private to insertion/src: the centroid of a hex and the area vector of a
// quad, shared by the insertion phases, adoptBoundary and the surface fit.
#include <array>
#include <cstddef>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex::insertion::detail {

inline Vec3 centroid(const HexMesh& mesh, Index h) {
    using vec::operator+;
    using vec::operator*;
    Vec3 c{0, 0, 0};
    for (Index v : mesh.hexes[static_cast<std::size_t>(h)]) c = c + mesh.nodes[static_cast<std::size_t>(v)];
    return 0.125 * c;
}

// Twice the area vector of the quad x0 x1 x2 x3 (right-hand normal): the
// cross product of its diagonals.
inline Vec3 quadAreaVector(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
    using vec::operator-;
    return vec::cross(x2 - x0, x3 - x1);
}

inline Vec3 quadAreaVector(const HexMesh& mesh, const std::array<Index, 4>& q) {
    const auto& x = mesh.nodes;
    return quadAreaVector(x[q[0]], x[q[1]], x[q[2]], x[q[3]]);
}

}  // namespace isohex::insertion::detail

#include "isohex/smoothing/NodeQuality.hpp"

#include <cstdint>

#include "NodeHexes.hpp"
#include "isohex/core/HexCell.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex::smoothing {

using namespace vec;

double usableScaledJacobian(const HexCoords& x) {
    const double s = scaledJacobian(x);
    return scaledJacobianCollapsed(s) ? -2.0 : s;
}

double minScaledJacobianAround(const HexMesh& mesh, const Topology& topo, Index v, const Vec3& p) {
    return detail::around(detail::NodeHexes(mesh, topo, v), p, 0.0).min;
}

Vec3 summedScaledJacobianGradient(const HexMesh& mesh, const Topology& topo, Index v, const Vec3& p) {
    return detail::NodeHexes(mesh, topo, v).summedGradient(p);
}

double meanEdgeLengthAt(const HexMesh& mesh, const Topology& topo, Index v) {
    double sum = 0;
    int count = 0;
    const auto sv = static_cast<std::size_t>(v);
    const Vec3& x = mesh.nodes[sv];
    for (const Index* h = topo.nodeHexes.begin(sv); h != topo.nodeHexes.end(sv); ++h) {
        const Hex& hx = mesh.hexes[static_cast<std::size_t>(*h)];
        for (int i = 0; i < 8; ++i) {
            if (hx[static_cast<std::size_t>(i)] != v) continue;
            for (int j : hexcell::kCornerNeighbours[static_cast<std::size_t>(i)]) {
                sum += norm(mesh.nodes[static_cast<std::size_t>(hx[static_cast<std::size_t>(j)])] - x);
                ++count;
            }
        }
    }
    return count ? sum / count : 0.0;
}

std::vector<Vec3> surfaceNormals(const HexMesh& mesh, const Topology& topo) {
    std::vector<Vec3> n(mesh.nodeCount(), Vec3{0, 0, 0});
    for (const Quad& q : topo.quads) {
        double sign = 1;  // quad nodes are in hex[0]'s order: the normal points out of hex[0]
        if (!q.boundary()) {
            const std::int32_t m0 = mesh.material[static_cast<std::size_t>(q.hex[0])];
            const std::int32_t m1 = mesh.material[static_cast<std::size_t>(q.hex[1])];
            if (m0 == m1) continue;
            if (m0 > m1) sign = -1;
        }
        const auto& x = mesh.nodes;
        const Vec3 a = sign * cross(x[q.nodes[2]] - x[q.nodes[0]], x[q.nodes[3]] - x[q.nodes[1]]);
        for (Index v : q.nodes) n[static_cast<std::size_t>(v)] = n[static_cast<std::size_t>(v)] + a;
    }
    for (Vec3& a : n) {
        const double l = norm(a);
        if (l > 0) a = (1.0 / l) * a;
    }
    return n;
}

}  // namespace isohex::smoothing

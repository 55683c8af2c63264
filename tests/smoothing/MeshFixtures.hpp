#pragma once
// Meshes for the smoothing tests: perturbed blocks and a block bent into a ball.
#include <algorithm>
#include <cmath>
#include <random>

#include "isohex/core/HexCell.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Pillow.hpp"
#include "isohex/core/Topology.hpp"
#include "Projectors.hpp"
#include "support/Blocks.hpp"

namespace isohex::test {

// An n^3 block of edge 2*radius centred at the origin whose nodes are pushed
// radially from cube shells onto sphere shells (x -> x |x|_inf / |x|_2), so the
// boundary nodes lie on the sphere of `radius`: the dual-contouring situation
// where each corner hex owns three faces on a curved surface. Boundary nodes
// are classified (one surface).
inline HexMesh ballFromBlock(int n, double radius) {
    const double h = 2.0 * radius / n;
    HexMesh m = makeBlock(n, n, n, h, {-radius, -radius, -radius});
    for (Vec3& p : m.nodes) {
        const double inf = std::max({std::abs(p[0]), std::abs(p[1]), std::abs(p[2])});
        const double two = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        if (two > 0)
            for (double& c : p) c *= inf / two;
    }
    classifyBoundaryNodes(m);
    return m;
}

// Moves every Interior node by a seeded uniform random offset of at most
// `amount` times the shortest edge at that node, per axis.
inline void perturbInterior(HexMesh& m, double amount, std::uint64_t seed) {
    std::vector<double> shortest(m.nodeCount(), 1e300);
    for (const Hex& h : m.hexes)
        for (const auto& e : hexcell::kEdges) {
            const Vec3 &a = m.nodes[h[e[0]]], &b = m.nodes[h[e[1]]];
            const double len = std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
            for (Index v : {h[e[0]], h[e[1]]}) shortest[v] = std::min(shortest[v], len);
        }
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-amount, amount);
    for (std::size_t v = 0; v < m.nodeCount(); ++v)
        if (m.nodeClass[v].kind == NodeKind::Interior)
            for (double& c : m.nodes[v]) c += u(rng) * shortest[v];
}

// The voxel cells of a grid (spacing 1) whose centres lie inside the sphere
// of `radius` at the origin, one hex per cell, with the boundary nodes then
// moved radially onto the sphere: the non-fundamental mesh dual contouring
// leaves before pillowing (interior cubes, bent boundary layer).
inline HexMesh voxelBall(double radius) {
    const int n = static_cast<int>(std::ceil(radius)) + 1;
    const int w = 2 * n + 1;  // nodes per axis, from -n to n
    auto inside = [&](int i, int j, int k) {  // cell with lower corner (i, j, k)
        const double x = i + 0.5, y = j + 0.5, z = k + 0.5;
        return x * x + y * y + z * z < radius * radius;
    };
    HexMesh m;
    std::vector<Index> id(static_cast<std::size_t>(w) * w * w, kNone);
    auto node = [&](int i, int j, int k) {
        Index& v = id[(static_cast<std::size_t>(k + n) * w + (j + n)) * w + (i + n)];
        if (v == kNone) v = m.addNode({double(i), double(j), double(k)});
        return v;
    };
    for (int k = -n; k < n; ++k)
        for (int j = -n; j < n; ++j)
            for (int i = -n; i < n; ++i)
                if (inside(i, j, k))
                    m.addHex({node(i, j, k), node(i + 1, j, k), node(i + 1, j + 1, k), node(i, j + 1, k),
                              node(i, j, k + 1), node(i + 1, j, k + 1), node(i + 1, j + 1, k + 1), node(i, j + 1, k + 1)});
    classifyBoundaryNodes(m);
    const SphereProjector sphere({0, 0, 0}, radius);
    for (std::size_t v = 0; v < m.nodeCount(); ++v)
        if (m.nodeClass[v].kind != NodeKind::Interior) m.nodes[v] = sphere.project(0, m.nodes[v]);
    return m;
}

inline double minScaledJacobian(const HexMesh& m) {
    const std::vector<double> sj = scaledJacobians(m);
    double lo = 1e300;
    for (double s : sj) lo = std::min(lo, s > 1.0 ? -1.0 : s);  // a degenerate hex counts as worst
    return lo;
}

}  // namespace isohex::test

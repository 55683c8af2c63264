#include "isohex/smoothing/BoundaryQuads.hpp"

#include <algorithm>
#include <cmath>

#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"

namespace isohex::smoothing {

namespace {

// The surface quads (boundary and interface) of each node.
std::vector<std::vector<Index>> surfaceQuadsOfNodes(const HexMesh& mesh, const Topology& topo) {
    std::vector<std::vector<Index>> of(mesh.nodes.size());
    for (const auto* list : {&topo.boundaryQuads, &topo.interfaceQuads})
        for (Index q : *list)
            for (Index v : topo.quads[static_cast<std::size_t>(q)].nodes) of[static_cast<std::size_t>(v)].push_back(q);
    return of;
}

// The smallest scaled Jacobian of the hexes around v (degenerate counts as 0).
double worstAround(const HexMesh& mesh, const Topology& topo, Index v) {
    double worst = 1;
    const auto n = static_cast<std::size_t>(v);
    for (const Index* h = topo.nodeHexes.begin(n); h != topo.nodeHexes.end(n); ++h) {
        const double s = scaledJacobian(hexCoords(mesh, *h));
        worst = std::min(worst, s > 1.0 + 1e-9 ? 0.0 : s);
    }
    return worst;
}

Vec3 lerp(const Vec3& a, const Vec3& b, double t) {
    return {a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])};
}

// One node's move; true when it moved.
bool moveNode(HexMesh& mesh, const SurfaceProjector& projector, const Topology& topo, Index v,
              const std::vector<Index>& quads) {
    const std::size_t i = static_cast<std::size_t>(v);
    Vec3 goal{0, 0, 0};
    for (Index q : quads)
        for (Index u : topo.quads[static_cast<std::size_t>(q)].nodes)
            for (int c = 0; c < 3; ++c) goal[c] += mesh.nodes[static_cast<std::size_t>(u)][c] / (4.0 * quads.size());
    const Vec3 start = mesh.nodes[i];
    const double before = worstAround(mesh, topo, v);
    const double floor = std::min(before, 0.2);
    for (double t = 1.0; t >= 0.125; t /= 2) {
        const Vec3 p = projector.project(mesh.nodeClass[i].id, lerp(start, goal, t));
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
        mesh.nodes[i] = p;
        if (worstAround(mesh, topo, v) >= floor) return true;
    }
    mesh.nodes[i] = start;
    return false;
}

}  // namespace

BoundaryQuadResult smoothBoundaryQuads(HexMesh& mesh, const SurfaceProjector& projector, const Topology& topo,
                                       int sweeps) {
    const Stopwatch clock;
    BoundaryQuadResult r;
    const std::vector<std::vector<Index>> quadsOf = surfaceQuadsOfNodes(mesh, topo);
    for (int s = 0; s < sweeps; ++s) {
        std::size_t moved = 0;
        for (std::size_t v = 0; v < mesh.nodes.size(); ++v) {
            const NodeClass& c = mesh.nodeClass[v];
            if (c.kind != NodeKind::Surface || quadsOf[v].empty() || !projector.projectsOnto(c.id)) continue;
            if (moveNode(mesh, projector, topo, static_cast<Index>(v), quadsOf[v])) ++moved;
        }
        ++r.sweeps;
        r.moves += moved;
        if (moved == 0) break;
    }
    r.seconds = clock.seconds();
    return r;
}

}  // namespace isohex::smoothing

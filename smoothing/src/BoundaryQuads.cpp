#include "isohex/smoothing/BoundaryQuads.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex::smoothing {

namespace {

using vec::cross;
using vec::dot;
using vec::norm;
using vec::operator-;
using vec::operator+;
using vec::operator*;

// The surface quads (boundary and interface), each with its nodes in the order
// whose right-hand normal points out of its first hex (boundary) or from the
// lower material to the higher (interface), and the quads of each node.
struct QuadSurface {
    std::vector<std::array<Index, 4>> quads;
    std::vector<std::vector<std::uint32_t>> of;  // per node, indices into quads
};

QuadSurface quadSurface(const HexMesh& mesh, const Topology& topo) {
    QuadSurface s;
    s.of.resize(mesh.nodes.size());
    for (const auto* list : {&topo.boundaryQuads, &topo.interfaceQuads})
        for (Index q : *list) {
            const Quad& quad = topo.quads[static_cast<std::size_t>(q)];
            std::array<Index, 4> n = quad.nodes;
            const bool flip = list == &topo.interfaceQuads &&
                              mesh.material[static_cast<std::size_t>(quad.hex[0])] >
                                  mesh.material[static_cast<std::size_t>(quad.hex[1])];
            if (flip) std::swap(n[1], n[3]);
            for (Index v : n) s.of[static_cast<std::size_t>(v)].push_back(static_cast<std::uint32_t>(s.quads.size()));
            s.quads.push_back(n);
        }
    return s;
}

// Unit normal at each surface node: the sum of its quads' diagonal normals.
std::vector<Vec3> nodeNormals(const HexMesh& mesh, const QuadSurface& s) {
    std::vector<Vec3> n(mesh.nodes.size(), Vec3{0, 0, 0});
    for (const auto& q : s.quads) {
        const auto& P = mesh.nodes;
        const Vec3 c = cross(P[static_cast<std::size_t>(q[2])] - P[static_cast<std::size_t>(q[0])],
                             P[static_cast<std::size_t>(q[3])] - P[static_cast<std::size_t>(q[1])]);
        for (Index v : q) n[static_cast<std::size_t>(v)] = n[static_cast<std::size_t>(v)] + c;
    }
    for (auto& v : n) {
        const double l = norm(v);
        if (l > 0) v = (1.0 / l) * v;
    }
    return n;
}

// The 2-D condition number of quad corner i, |a|^2 + |b|^2 over 2 det, with
// det measured against the corner node's normal: 1 for a right angle between
// equal edges, growing towards a flat or folded corner. A corner whose det is
// below 1e-3 of its scale costs 1000 and more the further it is folded, so
// that unfolding it is a descent too.
double cornerCost(const std::vector<Vec3>& P, const std::vector<Vec3>& normal, const std::array<Index, 4>& q, int i) {
    const Vec3& p = P[static_cast<std::size_t>(q[i])];
    const Vec3 a = P[static_cast<std::size_t>(q[(i + 1) % 4])] - p;
    const Vec3 b = P[static_cast<std::size_t>(q[(i + 3) % 4])] - p;
    const double scale = 0.5 * (dot(a, a) + dot(b, b));
    if (!(scale > 0)) return 2000;
    const double det = dot(cross(a, b), normal[static_cast<std::size_t>(q[i])]);
    const double eps = 1e-3 * scale;
    return det > eps ? scale / det : 1000 + 1000 * (eps - det) / scale;
}

// The cost of the corners node v's position changes: in each of its quads,
// its own corner and the two next to it.
double nodeCost(const std::vector<Vec3>& P, const std::vector<Vec3>& normal, const QuadSurface& s, Index v) {
    double sum = 0;
    for (std::uint32_t qi : s.of[static_cast<std::size_t>(v)]) {
        const auto& q = s.quads[qi];
        const int i = static_cast<int>(std::find(q.begin(), q.end(), v) - q.begin());
        for (int d : {0, 1, 3}) sum += cornerCost(P, normal, q, (i + d) % 4);
    }
    return sum;
}

// Two unit vectors spanning the plane normal to n.
std::array<Vec3, 2> tangents(const Vec3& n) {
    const Vec3 axis = std::abs(n[0]) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    Vec3 t1 = cross(n, axis);
    t1 = (1.0 / norm(t1)) * t1;
    return {t1, cross(n, t1)};
}

struct NodeStep {
    const HexMesh& mesh;
    const SurfaceProjector& projector;
    const QuadSurface& surface;
    const std::vector<Vec3>& normal;
};

// A compass search for node v on its surface: the centre of its quads and four
// tangent steps, each projected back onto the surface; the lowest cost below
// the start's is taken, else the step is halved (four times at most).
bool moveNode(HexMesh& mesh, const NodeStep& c, Index v) {
    const std::size_t i = static_cast<std::size_t>(v);
    const Vec3 start = mesh.nodes[i];
    const double before = nodeCost(mesh.nodes, c.normal, c.surface, v);
    Vec3 centre{0, 0, 0};
    double edge = 0;
    const auto& quads = c.surface.of[i];
    for (std::uint32_t qi : quads) {
        const auto& q = c.surface.quads[qi];
        for (Index u : q) centre = centre + (0.25 / static_cast<double>(quads.size())) * mesh.nodes[static_cast<std::size_t>(u)];
        const int k = static_cast<int>(std::find(q.begin(), q.end(), v) - q.begin());
        edge += norm(mesh.nodes[static_cast<std::size_t>(q[(k + 1) % 4])] - start);
    }
    edge /= static_cast<double>(quads.size());
    const auto [t1, t2] = tangents(c.normal[i]);
    double step = 0.25 * edge;
    for (int halving = 0; halving < 5; ++halving, step *= 0.5) {
        const Vec3 tries[5] = {start + (std::pow(0.5, halving)) * (centre - start), start + step * t1,
                               start - step * t1, start + step * t2, start - step * t2};
        double best = before * (1 - 1e-9);
        Vec3 bestAt = start;
        for (const Vec3& x : tries) {
            const Vec3 p = c.projector.project(mesh.nodeClass[i].id, x);
            if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
            mesh.nodes[i] = p;
            const double cost = nodeCost(mesh.nodes, c.normal, c.surface, v);
            if (cost < best) {
                best = cost;
                bestAt = p;
            }
        }
        mesh.nodes[i] = bestAt;
        if (bestAt != start) return true;
    }
    return false;
}

}  // namespace

BoundaryQuadResult smoothBoundaryQuads(HexMesh& mesh, const SurfaceProjector& projector, const Topology& topo,
                                       const BoundaryQuadOptions& options) {
    const Stopwatch clock;
    BoundaryQuadResult r;
    const QuadSurface surface = quadSurface(mesh, topo);
    for (int s = 0; s < options.sweeps; ++s) {
        const std::vector<Vec3> normal = nodeNormals(mesh, surface);
        const NodeStep step{mesh, projector, surface, normal};
        std::size_t moved = 0;
        for (std::size_t v = 0; v < mesh.nodes.size(); ++v) {
            const NodeClass& c = mesh.nodeClass[v];
            if (c.kind != NodeKind::Surface || surface.of[v].empty() || !projector.projectsOnto(c.id)) continue;
            if (moveNode(mesh, step, static_cast<Index>(v))) ++moved;
        }
        ++r.sweeps;
        r.moves += moved;
        if (moved == 0) break;
    }
    r.seconds = clock.seconds();
    return r;
}

}  // namespace isohex::smoothing

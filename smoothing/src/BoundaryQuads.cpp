#include "isohex/smoothing/BoundaryQuads.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex::smoothing {

namespace {

// A surface node within this fraction of its mean edge of its projection is
// on its surface (as the optimiser's surface step decides).
constexpr double kOnSurface = 1e-3;

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

// The 2-D condition number of the corner between edges a and b, |a|^2 +
// |b|^2 over 2 det, with det measured against the unit normal n: 1 for a
// right angle between equal edges, growing towards a flat or folded corner.
// A corner whose det is below 1e-3 of its scale costs 1000 and more the
// further it is folded, so that unfolding it is a descent too.
double conditionCost(const Vec3& a, const Vec3& b, const Vec3& n) {
    const double scale = 0.5 * (dot(a, a) + dot(b, b));
    if (!(scale > 0)) return 2000;
    const double det = dot(cross(a, b), n);
    const double eps = 1e-3 * scale;
    return det > eps ? scale / det : 1000 + 1000 * (eps - det) / scale;
}

// The edges of the corner of quad q at its node i.
std::pair<Vec3, Vec3> cornerEdges(const std::vector<Vec3>& P, const std::array<Index, 4>& q, int i) {
    const Vec3& p = P[static_cast<std::size_t>(q[i])];
    return {P[static_cast<std::size_t>(q[(i + 1) % 4])] - p, P[static_cast<std::size_t>(q[(i + 3) % 4])] - p};
}

int cornerOf(const std::array<Index, 4>& q, Index v) {
    return static_cast<int>(std::find(q.begin(), q.end(), v) - q.begin());
}

// Quad corner i against the corner node's normal of the sweep.
double cornerCost(const std::vector<Vec3>& P, const std::vector<Vec3>& normal, const std::array<Index, 4>& q, int i) {
    const auto [a, b] = cornerEdges(P, q, i);
    return conditionCost(a, b, normal[static_cast<std::size_t>(q[i])]);
}

// The corners at surface node u, each against the mean of u's unit corner
// normals where the nodes are now: the direction a pillow sheet's copy of u
// takes (PillowOptions::turnIntoCorners), so each term bounds the scaled
// Jacobian of the sheet hex on that corner once the surface is fixed. A fold
// at u (corners facing apart) costs here however good each quad's angles;
// the sweep's normals, fixed while the nodes move, do not see it arise.
double pillowCorners(const std::vector<Vec3>& P, const QuadSurface& s, Index u) {
    const auto& quads = s.of[static_cast<std::size_t>(u)];
    Vec3 m{0, 0, 0};
    for (std::uint32_t qi : quads) {
        const auto [a, b] = cornerEdges(P, s.quads[qi], cornerOf(s.quads[qi], u));
        const Vec3 n = cross(a, b);
        const double l = norm(n);
        if (l > 0) m = m + (1.0 / l) * n;
    }
    const double lm = norm(m);
    if (!(lm > 0)) return 2000.0 * static_cast<double>(quads.size());
    m = (1.0 / lm) * m;
    double sum = 0;
    for (std::uint32_t qi : quads) {
        const auto [a, b] = cornerEdges(P, s.quads[qi], cornerOf(s.quads[qi], u));
        sum += conditionCost(a, b, m);
    }
    return sum;
}

// Node v and each node it shares a quad edge with, once each, in the order of
// v's quads: the nodes whose pillow corners v's position changes.
std::vector<Index> edgeNeighbourhood(const QuadSurface& s, Index v) {
    std::vector<Index> near{v};
    for (std::uint32_t qi : s.of[static_cast<std::size_t>(v)]) {
        const auto& q = s.quads[qi];
        const int i = cornerOf(q, v);
        for (int d : {1, 3})
            if (std::find(near.begin(), near.end(), q[(i + d) % 4]) == near.end()) near.push_back(q[(i + d) % 4]);
    }
    return near;
}

// The cost node v's position changes: in each of its quads its own corner and
// the two next to it, against the sweep's normals; and the pillow corners
// (pillowCorners) of the nodes of `near` (edgeNeighbourhood(s, v), the same
// for every position the visit tries).
double nodeCost(const std::vector<Vec3>& P, const std::vector<Vec3>& normal, const QuadSurface& s, Index v,
                const std::vector<Index>& near) {
    double sum = 0;
    for (std::uint32_t qi : s.of[static_cast<std::size_t>(v)]) {
        const auto& q = s.quads[qi];
        const int i = cornerOf(q, v);
        for (int d : {0, 1, 3}) sum += cornerCost(P, normal, q, (i + d) % 4);
    }
    for (Index u : near) sum += pillowCorners(P, s, u);
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
// the start's is taken, else the step is halved (four times at most). A node
// off its surface (a vertex contouring held back so that no hex starts
// inverted) goes onto it, to the cheapest of those points and its own
// projection, whatever the cost: the protocol fixes the surface nodes on
// the isosurface. Returns 0 (stayed), 1 (moved) or 2 (moved onto its surface).
int moveNode(HexMesh& mesh, const NodeStep& c, Index v) {
    const std::size_t i = static_cast<std::size_t>(v);
    const Vec3 start = mesh.nodes[i];
    const std::vector<Index> near = edgeNeighbourhood(c.surface, v);
    const double before = nodeCost(mesh.nodes, c.normal, c.surface, v, near);
    Vec3 centre{0, 0, 0};
    double edge = 0;
    const auto& quads = c.surface.of[i];
    for (std::uint32_t qi : quads) {
        const auto& q = c.surface.quads[qi];
        for (Index u : q) centre = centre + (0.25 / static_cast<double>(quads.size())) * mesh.nodes[static_cast<std::size_t>(u)];
        edge += norm(mesh.nodes[static_cast<std::size_t>(q[(cornerOf(q, v) + 1) % 4])] - start);
    }
    edge /= static_cast<double>(quads.size());
    const std::int32_t surface = mesh.nodeClass[i].id;
    const bool off = !(norm(c.projector.project(surface, start) - start) <= kOnSurface * edge);
    const auto [t1, t2] = tangents(c.normal[i]);
    double step = 0.25 * edge;
    for (int halving = 0; halving < 5; ++halving, step *= 0.5) {
        const Vec3 tries[6] = {start + (std::pow(0.5, halving)) * (centre - start), start + step * t1,
                               start - step * t1, start + step * t2, start - step * t2, start};
        double best = off ? std::numeric_limits<double>::infinity() : before * (1 - 1e-9);
        Vec3 bestAt = start;
        for (const Vec3& x : tries) {
            const Vec3 p = c.projector.project(surface, x);
            if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
            mesh.nodes[i] = p;
            const double cost = nodeCost(mesh.nodes, c.normal, c.surface, v, near);
            if (cost < best) {
                best = cost;
                bestAt = p;
            }
        }
        mesh.nodes[i] = bestAt;
        if (bestAt != start) return off ? 2 : 1;
    }
    return 0;
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
            const int m = moveNode(mesh, step, static_cast<Index>(v));
            moved += m > 0;
            r.ontoSurface += m == 2;
        }
        ++r.sweeps;
        r.moves += moved;
        if (moved == 0) break;
    }
    r.seconds = clock.seconds();
    return r;
}

}  // namespace isohex::smoothing

#include "isohex/insertion/SheetGeometry.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "isohex/core/Topology.hpp"
#include "isohex/core/VecMath.hpp"

#include "ElementGeometry.hpp"

namespace isohex::insertion {

using namespace vec;

// ------------------------------------------------------------ projections

std::int32_t SheetGeometry::addTree(std::shared_ptr<const TriangleTree> tree) {
    trees.push_back(std::move(tree));
    return static_cast<std::int32_t>(trees.size() - 1);
}

Vec3 SheetGeometry::project(std::int32_t surfaceId, const Vec3& x) const {
    if (surfaceId < 0 || static_cast<std::size_t>(surfaceId) >= surfaceTree.size() || surfaceTree[surfaceId] < 0)
        return x;
    return trees[static_cast<std::size_t>(surfaceTree[surfaceId])]->closestPoint(x);
}

Vec3 SheetGeometry::projectToIntersection(std::int32_t a, std::int32_t b, const Vec3& x) const {
    const TriangleTree& A = *trees[static_cast<std::size_t>(a)];
    const TriangleTree& B = *trees[static_cast<std::size_t>(b)];
    // Alternating projections converge to a point of both surfaces where they
    // cross at an angle (linearly, at the rate cos^2 of that angle).
    Vec3 p = x;
    const double tol = 1e-12 * (1.0 + norm(x));
    for (int k = 0; k < 200; ++k) {
        const Vec3 q = A.closestPoint(p);
        const Vec3 r = B.closestPoint(q);
        const double gap = norm(r - q);
        p = r;
        if (gap <= tol) break;
    }
    return p;
}

Vec3 SheetGeometry::projectToCurve(std::int32_t curveId, const Vec3& x) const {
    if (curveId < 0 || static_cast<std::size_t>(curveId) >= curves.size()) return x;
    return projectToIntersection(curves[curveId][0], curves[curveId][1], x);
}

Vec3 SheetGeometry::projectToCurveCrossing(std::int32_t curveId, const TriangleTree& surface, const Vec3& x) const {
    const auto [a, b] = curves[static_cast<std::size_t>(curveId)];
    const TriangleTree& A = *trees[static_cast<std::size_t>(a)];
    const TriangleTree& B = *trees[static_cast<std::size_t>(b)];
    // Alternating projections onto the three surfaces, until a round moves
    // the point by (relatively) nothing.
    Vec3 p = x;
    for (int it = 0; it < 300; ++it) {
        const Vec3 q = B.closestPoint(A.closestPoint(surface.closestPoint(p)));
        const double step = norm(q - p);
        p = q;
        if (step <= 1e-12 * (1.0 + norm(p))) break;
    }
    return p;
}

// ------------------------------------------------------------ adoptBoundary

namespace {

// One tree per surface of the mesh (outer boundary or interface between
// materials), two triangles per quad, so that its nodes can be projected
// back onto it; surfaces without quads keep surfaceTree -1.
void addSurfaceTrees(const HexMesh& mesh, const Topology& topo, SheetGeometry& geometry) {
    const std::vector<SurfacePatch> patches = surfacePatches(mesh, topo);
    geometry.surfaceTree.assign(mesh.surfaces.size(), -1);
    std::vector<Index> local(mesh.nodeCount(), kNone);  // mesh node -> tree vertex, reset after each surface
    for (std::size_t s = 0; s < patches.size() && s < mesh.surfaces.size(); ++s) {
        std::vector<Vec3> vertices;
        std::vector<Index> used;
        std::vector<std::array<std::int32_t, 3>> tris;
        auto id = [&](Index v) {
            if (local[v] == kNone) {
                local[v] = static_cast<Index>(vertices.size());
                vertices.push_back(mesh.nodes[v]);
                used.push_back(v);
            }
            return local[v];
        };
        for (Index q : patches[s].quads) {
            const auto& n = topo.quads[static_cast<std::size_t>(q)].nodes;
            const Index a = id(n[0]), b = id(n[1]), c = id(n[2]), d = id(n[3]);
            tris.push_back({a, b, c});
            tris.push_back({a, c, d});
        }
        for (Index v : used) local[v] = kNone;
        if (tris.empty()) continue;
        geometry.surfaceTree[s] = geometry.addTree(
            std::make_shared<TriangleTree>(std::move(vertices), std::move(tris), surfaceName(mesh.surfaces[s])));
    }
}

// Nodes on sharp boundary edges: the two boundary quads of the edge meet at
// more than the feature angle (a crease two triangle trees cannot hold).
std::vector<std::uint8_t> sharpEdgeNodes(const HexMesh& mesh, const Topology& topo, double featureAngleDegrees) {
    const double cosLimit = std::cos(featureAngleDegrees * M_PI / 180.0);
    std::unordered_map<std::uint64_t, Vec3> firstNormal;
    std::vector<std::uint8_t> sharp(mesh.nodeCount(), 0);
    for (Index q : topo.boundaryQuads) {
        const auto& n = topo.quads[static_cast<std::size_t>(q)].nodes;
        Vec3 nq = detail::quadAreaVector(mesh, n);
        const double len = norm(nq);
        if (len > 0) nq = (1.0 / len) * nq;
        for (int i = 0; i < 4; ++i) {
            const Index a = std::min(n[i], n[(i + 1) % 4]), b = std::max(n[i], n[(i + 1) % 4]);
            const std::uint64_t key = (static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b);
            auto [it, fresh] = firstNormal.emplace(key, nq);
            if (!fresh && dot(it->second, nq) < cosLimit) sharp[a] = sharp[b] = 1;
        }
    }
    return sharp;
}

// Fixes the surface nodes on sharp edges and every curve node: the curves
// between a mesh's own surfaces have no geometry to slide along.
std::size_t fixUnknownNodes(HexMesh& mesh, const std::vector<std::uint8_t>& sharp) {
    std::size_t fixed = 0;
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v) {
        NodeClass& c = mesh.nodeClass[v];
        if ((sharp[v] && c.kind == NodeKind::Surface) || c.kind == NodeKind::Curve) {
            c = NodeClass{NodeKind::Fixed, -1};
            ++fixed;
        }
    }
    return fixed;
}

}  // namespace

std::size_t adoptBoundary(HexMesh& mesh, SheetGeometry& geometry, double featureAngleDegrees) {
    classifyBoundaryNodes(mesh);
    const Topology topo = buildTopology(mesh);
    addSurfaceTrees(mesh, topo, geometry);
    return fixUnknownNodes(mesh, sharpEdgeNodes(mesh, topo, featureAngleDegrees));
}

}  // namespace isohex::insertion

#include "isohex/smoothing/NodePlace.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "isohex/core/VecMath.hpp"

namespace isohex::smoothing {

using namespace isohex::vec;

const std::vector<std::int32_t>* JunctionSurfaces::of(Index v) const {
    const auto it = std::lower_bound(nodes.begin(), nodes.end(), v);
    if (it == nodes.end() || *it != v) return nullptr;
    return &surfaces[static_cast<std::size_t>(it - nodes.begin())];
}

namespace {

std::vector<Index> junctionNodes(const HexMesh& mesh) {
    std::vector<Index> nodes;
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v)
        if (mesh.nodeClass[v].kind == NodeKind::Curve && mesh.nodeClass[v].id < 0) nodes.push_back(static_cast<Index>(v));
    return nodes;
}

// The surfaces of `nodes` (junction nodes, ascending) from the surface quads of `topo`.
JunctionSurfaces surfacesOf(const HexMesh& mesh, const Topology& topo, std::vector<Index> nodes) {
    JunctionSurfaces j;
    j.nodes = std::move(nodes);
    j.surfaces.assign(j.nodes.size(), {});
    std::vector<std::uint8_t> unnamed(j.nodes.size(), 0);  // next to a surface the mesh does not name
    for (const SurfacePatch& p : surfacePatches(mesh, topo)) {
        const auto tag = std::find_if(mesh.surfaces.begin(), mesh.surfaces.end(), [&](const SurfaceTag& t) {
            return t.inside == p.tag.inside && t.outside == p.tag.outside;
        });
        const auto id = static_cast<std::int32_t>(tag - mesh.surfaces.begin());
        for (Index q : p.quads)
            for (Index u : topo.quads[static_cast<std::size_t>(q)].nodes) {
                const auto it = std::lower_bound(j.nodes.begin(), j.nodes.end(), u);
                if (it == j.nodes.end() || *it != u) continue;
                const auto k = static_cast<std::size_t>(it - j.nodes.begin());
                std::vector<std::int32_t>& ids = j.surfaces[k];
                if (tag == mesh.surfaces.end()) unnamed[k] = 1;
                else if (std::find(ids.begin(), ids.end(), id) == ids.end()) ids.push_back(id);
            }
    }
    for (std::size_t k = 0; k < j.nodes.size(); ++k) {
        if (unnamed[k]) j.surfaces[k].clear();  // no bound on that surface: the node stays fixed
        std::sort(j.surfaces[k].begin(), j.surfaces[k].end());
    }
    return j;
}

}  // namespace

JunctionSurfaces junctionSurfaces(const HexMesh& mesh) {
    std::vector<Index> nodes = junctionNodes(mesh);
    if (nodes.empty()) return {};
    return surfacesOf(mesh, buildTopology(mesh, TopologyParts::Surfaces), std::move(nodes));
}

JunctionSurfaces junctionSurfaces(const HexMesh& mesh, const Topology& topo) {
    std::vector<Index> nodes = junctionNodes(mesh);
    if (nodes.empty()) return {};
    return surfacesOf(mesh, topo, std::move(nodes));
}

std::vector<double> distancesFromPlace(const HexMesh& mesh, const SurfaceProjector& projector,
                                       const JunctionSurfaces& junctions, Index v, const Vec3& p) {
    const NodeClass& c = mesh.nodeClass[static_cast<std::size_t>(v)];
    if (c.kind == NodeKind::Surface) return {norm(projector.project(c.id, p) - p)};
    if (c.kind != NodeKind::Curve) return {};
    if (c.id >= 0) return {norm(projector.projectToCurve(c.id, p) - p)};
    std::vector<double> d;
    if (const std::vector<std::int32_t>* ids = junctions.of(v))
        for (const std::int32_t id : *ids) d.push_back(norm(projector.project(id, p) - p));
    return d;
}

double distanceFromPlace(const HexMesh& mesh, const SurfaceProjector& projector, const JunctionSurfaces& junctions,
                         Index v, const Vec3& p) {
    const NodeKind kind = mesh.nodeClass[static_cast<std::size_t>(v)].kind;
    if (kind != NodeKind::Surface && kind != NodeKind::Curve) return 0.0;
    const std::vector<double> d = distancesFromPlace(mesh, projector, junctions, v, p);
    if (d.empty()) return std::numeric_limits<double>::quiet_NaN();
    double off = 0;
    for (const double e : d) {
        if (std::isnan(e)) return e;
        off = std::max(off, e);
    }
    return off;
}

}  // namespace isohex::smoothing

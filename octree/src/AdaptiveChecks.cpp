// The checks of the adaptive mesher (AdaptiveSurface.hpp): where the placed
// mesh needs finer leaves.
#include <algorithm>
#include <cmath>
#include <limits>

#include <tbb/parallel_for.h>

#include "AdaptiveSurfaceParts.hpp"
#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Quality.hpp"

namespace isohex::octree {

namespace {

bool anyMoved(const PlacedMesh& p, const SurfaceQuad& q) {
    for (Index h : q.hex)
        if (h != kNone && p.a.hexLevel[static_cast<std::size_t>(h)] > 0) return true;
    for (Index v : q.nodes)
        if (p.moved[static_cast<std::size_t>(v)]) return true;
    return false;
}

// Edges of one surface's quads in other than two of them: their nodes.
void nonManifoldEdges(const PlacedMesh& p, std::vector<Index>& out) {
    std::vector<std::array<std::int64_t, 3>> e;  // surface, smaller node, larger node
    e.reserve(p.quads.size() * 4);
    for (const SurfaceQuad& q : p.quads)
        for (int c = 0; c < 4; ++c) {
            const Index a = q.nodes[static_cast<std::size_t>(c)], b = q.nodes[static_cast<std::size_t>((c + 1) % 4)];
            e.push_back({q.surface, std::min(a, b), std::max(a, b)});
        }
    std::sort(e.begin(), e.end());
    for (std::size_t i = 0; i < e.size();) {
        std::size_t j = i;
        while (j < e.size() && e[j] == e[i]) ++j;
        if (j - i != 2) {
            out.push_back(static_cast<Index>(e[i][1]));
            out.push_back(static_cast<Index>(e[i][2]));
        }
        i = j;
    }
}

// Nodes whose quads of one surface are not one fan (two cones touching).
void nonManifoldFans(const PlacedMesh& p, std::vector<Index>& out) {
    struct Corner {
        Index node;
        std::int32_t surface;
        Index prev, next;
        bool operator<(const Corner& o) const {
            return std::tie(node, surface, prev, next) < std::tie(o.node, o.surface, o.prev, o.next);
        }
    };
    std::vector<Corner> c;
    c.reserve(p.quads.size() * 4);
    for (const SurfaceQuad& q : p.quads)
        for (int k = 0; k < 4; ++k)
            c.push_back({q.nodes[static_cast<std::size_t>(k)], q.surface, q.nodes[static_cast<std::size_t>((k + 3) % 4)],
                         q.nodes[static_cast<std::size_t>((k + 1) % 4)]});
    std::sort(c.begin(), c.end());
    std::vector<Index> ends;
    DisjointSets<std::int32_t> sets;
    for (std::size_t i = 0; i < c.size();) {
        std::size_t j = i;
        while (j < c.size() && c[j].node == c[i].node && c[j].surface == c[i].surface) ++j;
        ends.clear();
        for (std::size_t k = i; k < j; ++k) ends.insert(ends.end(), {c[k].prev, c[k].next});
        std::sort(ends.begin(), ends.end());
        ends.erase(std::unique(ends.begin(), ends.end()), ends.end());
        sets.reset(ends.size());
        const auto slot = [&](Index v) {
            return static_cast<std::int32_t>(std::lower_bound(ends.begin(), ends.end(), v) - ends.begin());
        };
        std::size_t parts = ends.size();
        for (std::size_t k = i; k < j; ++k) {
            const std::int32_t a = slot(c[k].prev), b = slot(c[k].next);
            if (sets.find(a) != sets.find(b)) {
                sets.unite(a, b);
                --parts;
            }
        }
        if (parts != 1) out.push_back(c[i].node);
        i = j;
    }
}

// |f| / |grad f| of material m at x, in world units.
double distanceTo(const Domain& d, std::int32_t m, const Vec3& x) {
    Vec3 g;
    const double f = d.value(m, x, &g);
    const double len = std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    if (!std::isfinite(f)) return 0;  // no field there (NaN voxels): nothing to judge
    // a flat field (a scan's plateau far from its isosurface) says "far"
    if (!(len > 1e-9 * std::abs(f))) return std::numeric_limits<double>::infinity();
    return std::abs(f) / len;
}

// Whether a quad's centre or an edge midpoint is farther than `tolerance`
// from its surface.
bool deviates(const PlacedMesh& p, const Domain& d, const SurfaceQuad& q, double tolerance) {
    const auto& x = p.a.mesh.nodes;
    Vec3 centre{0, 0, 0};
    for (int c = 0; c < 4; ++c) {
        const Vec3& a = x[static_cast<std::size_t>(q.nodes[static_cast<std::size_t>(c)])];
        const Vec3& b = x[static_cast<std::size_t>(q.nodes[static_cast<std::size_t>((c + 1) % 4)])];
        for (int k = 0; k < 3; ++k) centre[k] += a[k] / 4;
        if (distanceTo(d, q.material, {(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2}) > tolerance) return true;
    }
    return distanceTo(d, q.material, centre) > tolerance;
}

}  // namespace

Problems findProblems(const PlacedMesh& p, const Domain& domain, double tolerance) {
    Problems out;
    const HexMesh& m = p.a.mesh;
    for (std::size_t n = 0; n < m.nodeCount(); ++n)
        if (p.junction[n]) out.nodes[static_cast<int>(RefineReason::Junction)].push_back(static_cast<Index>(n));
    auto& manifold = out.nodes[static_cast<int>(RefineReason::NonManifold)];
    nonManifoldEdges(p, manifold);
    nonManifoldFans(p, manifold);
    std::vector<std::uint8_t> bad(m.hexCount(), 0);
    tbb::parallel_for(std::size_t{0}, m.hexCount(), [&](std::size_t h) {
        bool moved = p.a.hexLevel[h] > 0;
        for (Index v : m.hexes[h]) moved = moved || p.moved[static_cast<std::size_t>(v)];
        bad[h] = moved && !(minJacobianDeterminant(hexCoords(m, static_cast<Index>(h))) > 0);
    });
    for (std::size_t h = 0; h < bad.size(); ++h)
        if (bad[h]) {
            out.hexes[static_cast<int>(RefineReason::Inverted)].push_back(static_cast<Index>(h));
            for (Index v : m.hexes[h])
                if (p.moved[static_cast<std::size_t>(v)]) out.nodes[static_cast<int>(RefineReason::Inverted)].push_back(v);
        }
    std::vector<std::uint8_t> far(p.quads.size(), 0);
    tbb::parallel_for(std::size_t{0}, p.quads.size(), [&](std::size_t q) {
        far[q] = anyMoved(p, p.quads[q]) && deviates(p, domain, p.quads[q], tolerance);
    });
    for (std::size_t q = 0; q < far.size(); ++q)
        if (far[q]) {
            for (Index h : p.quads[q].hex)
                if (h != kNone) out.hexes[static_cast<int>(RefineReason::Deviation)].push_back(h);
            for (Index v : p.quads[q].nodes)
                if (p.moved[static_cast<std::size_t>(v)]) out.nodes[static_cast<int>(RefineReason::Deviation)].push_back(v);
        }
    return out;
}

}  // namespace isohex::octree

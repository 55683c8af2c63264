#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/PolygonRegions.hpp"
#include "isohex/octree/Regions.hpp"
#include "isohex/octree/TopologyMatch.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include <openvdb/tools/VolumeToMesh.h>

#include "isohex/core/DisjointSets.hpp"

namespace isohex::octree {

namespace {

// volumeToMesh's polygons of one material's grid points.
struct Polygons {
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
};

// The index box of each material's grid points.
std::map<std::int32_t, openvdb::CoordBBox> materialBoxes(const Labels& l) {
    const auto [nx, ny, nz] = l.grid.dims;
    std::map<std::int32_t, openvdb::CoordBBox> boxes;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                if (const std::int32_t m = l.material[l.grid.index(i, j, k)]; m != 0)
                    boxes[m].expand(openvdb::Coord(i, j, k));
    return boxes;
}

// The polygonisation of material m's grid points (-1 inside, 1 outside) in
// `box` (already grown by one point).
Polygons polygonise(const Labels& l, std::int32_t m, const openvdb::CoordBBox& box) {
    const Grid& g = l.grid;
    const auto [nx, ny, nz] = g.dims;
    auto grid = openvdb::FloatGrid::create(1.0f);
    auto acc = grid->getAccessor();
    for (int k = std::max(box.min().z(), 0); k <= std::min(box.max().z(), nz - 1); ++k)
        for (int j = std::max(box.min().y(), 0); j <= std::min(box.max().y(), ny - 1); ++j)
            for (int i = std::max(box.min().x(), 0); i <= std::min(box.max().x(), nx - 1); ++i)
                if (l.material[g.index(i, j, k)] == m) acc.setValue(openvdb::Coord(i, j, k), -1.0f);
    Polygons p;
    openvdb::tools::volumeToMesh(*grid, p.points, p.triangles, p.quads, 0.0);
    return p;
}

// Connected components of the polygons, over their vertices.
DisjointSets<std::uint32_t> surfaceComponents(const Polygons& s) {
    DisjointSets<std::uint32_t> surface(s.points.size());
    for (const auto& q : s.quads)
        for (int e = 0; e < 4; ++e) surface.unite(q[e], q[(e + 1) % 4]);
    for (const auto& t : s.triangles)
        for (int e = 0; e < 3; ++e) surface.unite(t[e], t[(e + 1) % 3]);
    return surface;
}

// Components and Euler characteristic (V - E + F) of material m's polygons.
RegionTopology polygonTopology(std::int32_t m, const Polygons& s, DisjointSets<std::uint32_t>& surface) {
    RegionTopology t;
    t.material = m;
    std::vector<std::uint64_t> edges;
    auto edge = [&](std::uint32_t a, std::uint32_t b) {
        edges.push_back(static_cast<std::uint64_t>(std::min(a, b)) << 32 | std::max(a, b));
    };
    for (const auto& q : s.quads)
        for (int e = 0; e < 4; ++e) edge(q[e], q[(e + 1) % 4]);
    for (const auto& tr : s.triangles)
        for (int e = 0; e < 3; ++e) edge(tr[e], tr[(e + 1) % 3]);
    std::sort(edges.begin(), edges.end());
    const auto e = static_cast<long long>(std::unique(edges.begin(), edges.end()) - edges.begin());
    std::vector<char> used(s.points.size(), 0);
    for (const auto& q : s.quads)
        for (int k = 0; k < 4; ++k) used[q[k]] = 1;
    for (const auto& tr : s.triangles)
        for (int k = 0; k < 3; ++k) used[tr[k]] = 1;
    long long v = 0;
    for (std::uint32_t a = 0; a < s.points.size(); ++a) {
        if (!used[a]) continue;
        ++v;
        t.components += surface.find(a) == a;
    }
    t.euler = v - e + static_cast<long long>(s.quads.size() + s.triangles.size());
    return t;
}

// Unites, per surface component, the grid points of material m on the inner
// side of its quads. The 4 vertices of a quad lie in the 4 cells around the
// crossed edge: equal cell coordinate along the edge, the edge's start the
// largest of the others.
void uniteInnerSides(const Labels& l, std::int32_t m, const Polygons& s, DisjointSets<std::uint32_t>& surface,
                     DisjointSets<std::uint32_t>& parts) {
    const Grid& g = l.grid;
    const auto [nx, ny, nz] = g.dims;
    std::vector<std::int64_t> inner(s.points.size(), -1);  // per surface component: a point on its inner side
    for (const auto& q : s.quads) {
        int c[4][3];
        for (int e = 0; e < 4; ++e)
            for (int a = 0; a < 3; ++a) c[e][a] = static_cast<int>(std::floor(s.points[q[e]][a]));
        int axis = -1;
        for (int a = 0; a < 3; ++a)
            if (c[0][a] == c[1][a] && c[0][a] == c[2][a] && c[0][a] == c[3][a]) axis = a;
        if (axis < 0) continue;
        int lo[3];
        for (int a = 0; a < 3; ++a) lo[a] = std::max(std::max(c[0][a], c[1][a]), std::max(c[2][a], c[3][a]));
        int hi[3] = {lo[0], lo[1], lo[2]};
        ++hi[axis];
        if (lo[0] < 0 || lo[1] < 0 || lo[2] < 0 || hi[0] >= nx || hi[1] >= ny || hi[2] >= nz) continue;
        const std::size_t a = g.index(lo[0], lo[1], lo[2]), b = g.index(hi[0], hi[1], hi[2]);
        if ((l.material[a] == m) == (l.material[b] == m)) continue;
        const std::size_t in = l.material[a] == m ? a : b;
        const std::uint32_t comp = surface.find(q[0]);
        if (inner[comp] < 0) inner[comp] = static_cast<std::int64_t>(in);
        else parts.unite(static_cast<std::uint32_t>(in), static_cast<std::uint32_t>(inner[comp]));
    }
}

}  // namespace

const CellEdgeGroups& volumeToMeshTables() {
    static const CellEdgeGroups table = [] {
        CellEdgeGroups t;
        for (int p = 0; p < 256; ++p) {
            for (int e = 0; e < 13; ++e) t.edgeGroups[p][e] = openvdb::tools::volume_to_mesh_internal::sEdgeGroupTable[p][e];
            t.ambiguousFace[p] = openvdb::tools::volume_to_mesh_internal::sAmbiguousFace[p];
        }
        return t;
    }();
    return table;
}

std::vector<std::int32_t> marchingCubesRegions(const Labels& l, std::vector<RegionTopology>* surfaces) {
    const std::size_t n = l.material.size();
    // Roots are the smallest member whatever the order of the unions, so the
    // ids do not depend on uniting the 6-adjacent points first.
    DisjointSets<std::uint32_t> parts = materialRegions(l, Adjacency::Face);
    std::map<std::int32_t, openvdb::CoordBBox> boxes = materialBoxes(l);
    for (auto& [m, box] : boxes) {
        box.expand(1);
        const Polygons s = polygonise(l, m, box);
        DisjointSets<std::uint32_t> surface = surfaceComponents(s);
        if (surfaces) surfaces->push_back(polygonTopology(m, s, surface));
        uniteInnerSides(l, m, s, surface, parts);
    }
    std::vector<std::int32_t> id(n, -1);
    for (std::size_t p = 0; p < n; ++p)
        if (l.material[p] != 0) id[p] = static_cast<std::int32_t>(parts.find(static_cast<std::uint32_t>(p)));
    return id;
}

}  // namespace isohex::octree

#include "isohex/core/Validate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"
#include "isohex/core/Parallel.hpp"
#include "isohex/core/Quality.hpp"

namespace isohex {

namespace {

// How many entities were flagged and the smallest of their ids. The result is a
// function of the flagged set only, so partial results can be merged in any
// order and the report does not depend on how TBB split the work.
struct Found {
    std::size_t count = 0;
    std::vector<Index> smallest;  // ascending, at most kMaxExamples

    void add(Index id) {
        ++count;
        keep(id);
    }
    void merge(const Found& o) {
        count += o.count;
        for (Index id : o.smallest) keep(id);
    }

private:
    void keep(Index id) {
        if (smallest.size() == kMaxExamples) {
            if (id >= smallest.back()) return;
            smallest.pop_back();
        }
        smallest.insert(std::upper_bound(smallest.begin(), smallest.end(), id), id);
    }
};

std::array<Index, 8> sortedNodes(const Hex& h) {
    std::array<Index, 8> s = h;
    std::sort(s.begin(), s.end());
    return s;
}

bool hasRepeatedNode(const Hex& h) {
    const auto s = sortedNodes(h);
    return std::adjacent_find(s.begin(), s.end()) != s.end();
}

bool sameNodeSet(const HexMesh& mesh, Index a, Index b) {
    return sortedNodes(mesh.hexes[a]) == sortedNodes(mesh.hexes[b]);
}

template <std::size_t K>
Vec3 centroid(const HexMesh& mesh, const std::array<Index, K>& ids) {
    Vec3 c{0, 0, 0};
    for (Index v : ids)
        for (int d = 0; d < 3; ++d) c[d] += mesh.nodes[v][d];
    for (int d = 0; d < 3; ++d) c[d] /= static_cast<double>(K);
    return c;
}

// The local face of `side` (0 or 1) of a quad that has two hexes.
int localFaceOf(const Topology& topo, Index q, int side) {
    const Quad& quad = topo.quads[q];
    if (quad.localFace[side] >= 0) return quad.localFace[side];
    const Index h = quad.hex[side];
    for (int f = 0; f < 6; ++f)
        if (topo.hexQuads[h][f] == q) return f;
    return -1;
}

std::array<Index, 4> faceNodes(const HexMesh& mesh, Index h, int f) {
    std::array<Index, 4> n;
    for (int i = 0; i < 4; ++i) n[i] = mesh.hexes[h][hexcell::kFaces[f][i]];
    return n;
}

// Undirected edges of a quad as (smaller, larger), collapsed edges left out.
int quadEdges(const std::array<Index, 4>& n, std::array<std::pair<Index, Index>, 4>& out) {
    int k = 0;
    for (int i = 0; i < 4; ++i) {
        const Index a = n[i], b = n[(i + 1) % 4];
        if (a == b) continue;
        const std::pair<Index, Index> e{std::min(a, b), std::max(a, b)};
        if (std::find(out.begin(), out.begin() + k, e) == out.begin() + k) out[k++] = e;
    }
    return k;
}

// ---------------------------------------------------------------- per hex

struct HexAcc {
    Found repeated, duplicate, doublet, inverted;
    void merge(const HexAcc& o) {
        repeated.merge(o.repeated);
        duplicate.merge(o.duplicate);
        doublet.merge(o.doublet);
        inverted.merge(o.inverted);
    }
};

HexAcc checkHexes(const HexMesh& mesh, const Topology& topo) {
    return parallel::reduceOver<HexAcc>(mesh.hexes.size(), 1024, [&](const auto& r, HexAcc& acc) {
        for (std::size_t hi = r.begin(); hi != r.end(); ++hi) {
            const Index h = static_cast<Index>(hi);
            const Hex& hex = mesh.hexes[hi];
            const auto key = sortedNodes(hex);
            const bool repeated = std::adjacent_find(key.begin(), key.end()) != key.end();
            if (repeated) acc.repeated.add(h);

            // Duplicate of a smaller hex: every candidate uses the smallest node,
            // and must also use the largest one before the full comparison.
            bool duplicate = false;
            const Index lo = key.front(), hiNode = key.back();
            for (const Index* g = topo.nodeHexes.begin(lo); g != topo.nodeHexes.end(lo) && !duplicate; ++g) {
                if (*g >= h) continue;
                const Hex& other = mesh.hexes[*g];
                if (std::find(other.begin(), other.end(), hiNode) == other.end()) continue;
                duplicate = sortedNodes(other) == key;
            }
            if (duplicate) acc.duplicate.add(h);

            // Doublet: one neighbour reached through two different quads.
            // Identical hexes share all their quads; they are reported as duplicates.
            std::array<std::pair<Index, Index>, 24> seen;  // (neighbour hex, quad)
            int nSeen = 0;
            bool doublet = false;
            for (int f = 0; f < 6 && !doublet; ++f) {
                const Index q = topo.hexQuads[hi][f];
                for (const Index* g = topo.quadHexesAll.begin(q); g != topo.quadHexesAll.end(q) && !doublet; ++g) {
                    if (*g == h) continue;
                    for (int s = 0; s < nSeen; ++s)
                        if (seen[s].first == *g && seen[s].second != q && !sameNodeSet(mesh, h, *g)) {
                            doublet = true;
                            break;
                        }
                    if (nSeen < static_cast<int>(seen.size())) seen[nSeen++] = {*g, q};
                }
            }
            if (doublet) acc.doublet.add(h);

            // A hex with a repeated node has zero determinants by construction;
            // it is reported once, as repeated_node. NaN counts as inverted.
            if (!repeated) {
                const HexCoords x = hexCoords(mesh, h);
                const double det = minJacobianDeterminant(x);
                if (!(det > 0.0)) acc.inverted.add(h);
            }
        }
    });
}

// ---------------------------------------------------------------- per quad

// Two hexes on opposite sides of a quad traverse it in opposite directions. If
// both traverse it the same way, one of them lies folded onto the other.
Found checkOrientation(const HexMesh& mesh, const Topology& topo) {
    return parallel::reduceOver<Found>(topo.quads.size(), 4096, [&](const auto& r, Found& acc) {
        for (std::size_t qi = r.begin(); qi != r.end(); ++qi) {
            const Index q = static_cast<Index>(qi);
            const Quad& quad = topo.quads[qi];
            if (quad.hex[1] == kNone || topo.quadHexesAll.size(qi) != 2) continue;  // boundary or overfull
            const Index h0 = quad.hex[0], h1 = quad.hex[1];
            if (h0 == h1 || hasRepeatedNode(mesh.hexes[h0]) || hasRepeatedNode(mesh.hexes[h1])) continue;
            const int f0 = localFaceOf(topo, q, 0), f1 = localFaceOf(topo, q, 1);
            if (f0 < 0 || f1 < 0) continue;
            const auto a = faceNodes(mesh, h0, f0);
            const auto b = faceNodes(mesh, h1, f1);
            const auto k = std::find(b.begin(), b.end(), a[0]) - b.begin();
            if (k == 4) continue;
            const bool same = b[(k + 1) % 4] == a[1] && b[(k + 3) % 4] == a[3];
            if (same && !sameNodeSet(mesh, h0, h1)) acc.add(q);
        }
    });
}

// ---------------------------------------------------------------- surfaces

// The quads of every surface patch, numbered consecutively patch by patch
// ("surface quads"), and for every node the surface quads that contain it.
struct SurfaceIndex {
    std::vector<Index> quad;     // surface quad -> quad id
    std::vector<Index> surface;  // surface quad -> patch id
    Csr nodeItems;               // node -> 4 * surface quad + corner, sorted (so grouped by patch)
};

SurfaceIndex indexSurfaces(const HexMesh& mesh, const Topology& topo) {
    SurfaceIndex s;
    const std::vector<SurfacePatch> patches = surfacePatches(mesh, topo);
    for (std::size_t p = 0; p < patches.size(); ++p)
        for (Index q : patches[p].quads) {
            s.quad.push_back(q);
            s.surface.push_back(static_cast<Index>(p));
        }
    s.nodeItems = parallel::bucketItems(mesh.nodes.size(), s.quad.size() * 4, [&](std::size_t i) {
        return topo.quads[s.quad[i / 4]].nodes[i % 4];
    });
    return s;
}

struct SurfaceAcc {
    Found nodes, edges;
    void merge(const SurfaceAcc& o) {
        nodes.merge(o.nodes);
        edges.merge(o.edges);
    }
};

// Edge id of (a, b), looked up through a hex known to contain it.
Index edgeId(const HexMesh& mesh, const Topology& topo, Index hex, Index a, Index b) {
    const Hex& h = mesh.hexes[hex];
    for (int e = 0; e < 12; ++e) {
        const Index u = h[hexcell::kEdges[e][0]], v = h[hexcell::kEdges[e][1]];
        if ((u == a && v == b) || (u == b && v == a)) return topo.hexEdges[hex][e];
    }
    return kNone;
}

// Per node and per surface: the fan test, and (at the smaller end of each
// edge) the count of that surface's quads on the edge.
SurfaceAcc checkSurfaceFans(const HexMesh& mesh, const Topology& topo, const SurfaceIndex& s) {
    const Csr& rows = s.nodeItems;
    return parallel::reduceOver<SurfaceAcc>(mesh.nodes.size(), 1024, [&](const auto& r, SurfaceAcc& acc) {
        std::vector<Index> row;                  // distinct surface quads at the node
        std::vector<std::pair<Index, int>> nb;   // (other end of an edge through v, position in row)
        DisjointSets<int> fanSets;               // the quads of one surface at the node, joined into fans
        std::vector<Index> badEdges;             // other ends of flagged edges (v < w)
        // Does a quad of another surface than `surf` in `row` have edge (v, w)?
        auto otherSurfaceHas = [&](Index v, Index w, Index surf) {
            for (Index sq : row) {
                if (s.surface[sq] == surf) continue;
                const auto& n = topo.quads[s.quad[sq]].nodes;
                for (int i = 0; i < 4; ++i) {
                    const Index a = n[i], b = n[(i + 1) % 4];
                    if ((a == v && b == w) || (a == w && b == v)) return true;
                }
            }
            return false;
        };
        for (std::size_t vi = r.begin(); vi != r.end(); ++vi) {
            if (rows.size(vi) == 0) continue;
            const Index v = static_cast<Index>(vi);
            row.clear();
            for (const Index* it = rows.begin(vi); it != rows.end(vi); ++it)
                if (row.empty() || row.back() != *it / 4) row.push_back(*it / 4);
            badEdges.clear();
            bool pinched = false;
            for (std::size_t g = 0; g < row.size();) {
                const Index surf = s.surface[row[g]];
                std::size_t e = g;
                while (e < row.size() && s.surface[row[e]] == surf) ++e;
                nb.clear();
                for (std::size_t i = g; i < e; ++i) {
                    const auto& n = topo.quads[s.quad[row[i]]].nodes;
                    for (int j = 0; j < 4; ++j) {
                        if (n[j] != v) continue;
                        for (Index w : {n[(j + 3) % 4], n[(j + 1) % 4]})
                            if (w != v) nb.emplace_back(w, static_cast<int>(i - g));
                    }
                }
                std::sort(nb.begin(), nb.end());
                nb.erase(std::unique(nb.begin(), nb.end()), nb.end());
                fanSets.reset(e - g);
                for (std::size_t a = 0; a < nb.size();) {
                    std::size_t b = a;
                    while (b < nb.size() && nb[b].first == nb[a].first) ++b;
                    const std::size_t quadsOnEdge = b - a;
                    // Only an edge with exactly two quads of this surface joins
                    // two quads into one fan.
                    if (quadsOnEdge == 2) fanSets.unite(nb[a].second, nb[a + 1].second);
                    const Index w = nb[a].first;
                    if (v < w && (quadsOnEdge >= 3 || (quadsOnEdge == 1 && !otherSurfaceHas(v, w, surf))))
                        badEdges.push_back(w);
                    a = b;
                }
                if (fanSets.countSets() > 1) pinched = true;
                g = e;
            }
            if (pinched) acc.nodes.add(v);
            std::sort(badEdges.begin(), badEdges.end());
            badEdges.erase(std::unique(badEdges.begin(), badEdges.end()), badEdges.end());
            for (Index w : badEdges) {
                // Any surface quad at v on edge (v, w) names a hex holding the edge.
                Index id = kNone;
                for (std::size_t i = 0; i < row.size() && id == kNone; ++i) {
                    const Quad& quad = topo.quads[s.quad[row[i]]];
                    if (std::find(quad.nodes.begin(), quad.nodes.end(), w) != quad.nodes.end())
                        id = edgeId(mesh, topo, quad.hex[0], v, w);
                }
                if (id != kNone) acc.edges.add(id);
            }
        }
    });
}

// Two surface quads (of any surfaces) sharing two or more edges.
Found checkQuadDoublets(const Topology& topo, const SurfaceIndex& s) {
    const Csr& rows = s.nodeItems;
    return parallel::reduceOver<Found>(s.quad.size(), 1024, [&](const auto& r, Found& acc) {
        for (std::size_t sq = r.begin(); sq != r.end(); ++sq) {
            const Index q = s.quad[sq];
            const auto& n = topo.quads[q].nodes;
            std::array<std::pair<Index, Index>, 4> mine, theirs;
            const int nMine = quadEdges(n, mine);
            bool doublet = false;
            for (int c = 0; c < 4 && !doublet; ++c) {
                const Index v = n[c];
                for (const Index* it = rows.begin(v); it != rows.end(v) && !doublet; ++it) {
                    const Index other = s.quad[*it / 4];
                    if (other == q) continue;
                    const int nTheirs = quadEdges(topo.quads[other].nodes, theirs);
                    int shared = 0;
                    for (int i = 0; i < nMine; ++i)
                        if (std::find(theirs.begin(), theirs.begin() + nTheirs, mine[i]) != theirs.begin() + nTheirs)
                            ++shared;
                    doublet = shared >= 2;
                }
            }
            if (doublet) acc.add(q);
        }
    });
}

// ---------------------------------------------------------------- coincident nodes

// Boundary nodes at the same place as another boundary node: a mesh whose
// hexes were written with their own copies of shared corners (unmerged
// nodes) has every hex on its own, each face a boundary face, and is no
// mesh of the solid. Positions count as equal when they fall in the same
// cell of a grid a millionth of the boundary's bounding box wide (exact
// copies always do; copies that differ in the last bits nearly always).
// Only boundary nodes are looked at: two distinct nodes at one place inside
// the solid would also leave their hexes with boundary faces there.
Found checkCoincidentNodes(const HexMesh& mesh, const Topology& topo) {
    std::vector<std::uint8_t> onBoundary(mesh.nodes.size(), 0);
    for (Index q : topo.boundaryQuads)
        for (Index v : topo.quads[q].nodes) onBoundary[v] = 1;
    std::vector<Index> nodes;
    Vec3 lo{std::numeric_limits<double>::max(), std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
    Vec3 hi{-lo[0], -lo[1], -lo[2]};
    for (std::size_t v = 0; v < onBoundary.size(); ++v) {
        if (!onBoundary[v]) continue;
        nodes.push_back(static_cast<Index>(v));
        for (int d = 0; d < 3; ++d) {
            lo[d] = std::min(lo[d], mesh.nodes[v][d]);
            hi[d] = std::max(hi[d], mesh.nodes[v][d]);
        }
    }
    Found found;
    if (nodes.size() < 2) return found;
    const double diagonal = std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                                      (hi[2] - lo[2]) * (hi[2] - lo[2]));
    if (!(diagonal > 0) || !std::isfinite(diagonal)) return found;
    const double cell = 1e-6 * diagonal;
    using Key = std::array<std::int64_t, 3>;
    std::vector<std::pair<Key, Index>> keyed(nodes.size());
    for (std::size_t i = 0; i < nodes.size(); ++i) {
        const Vec3& p = mesh.nodes[nodes[i]];
        keyed[i] = {{static_cast<std::int64_t>(std::floor((p[0] - lo[0]) / cell)),
                     static_cast<std::int64_t>(std::floor((p[1] - lo[1]) / cell)),
                     static_cast<std::int64_t>(std::floor((p[2] - lo[2]) / cell))},
                    nodes[i]};
    }
    std::sort(keyed.begin(), keyed.end());
    for (std::size_t a = 0; a < keyed.size();) {
        std::size_t b = a + 1;
        while (b < keyed.size() && keyed[b].first == keyed[a].first) ++b;
        if (b - a > 1)
            for (std::size_t i = a; i < b; ++i) found.add(keyed[i].second);
        a = b;
    }
    return found;
}

// ---------------------------------------------------------------- report

void put(ValidityReport& report, const char* key, const char* constraint, const char* entity,
         const char* description, const Found& found, const std::vector<Vec3>& where) {
    if (found.count == 0) return;
    DefectKind& d = report.defects[key];
    d.constraint = constraint;
    d.description = description;
    d.entity = entity;
    d.count = found.count;
    d.examples = found.smallest;
    d.where = where;
}

std::vector<Vec3> hexWhere(const HexMesh& mesh, const Found& f) {
    std::vector<Vec3> w;
    for (Index h : f.smallest) w.push_back(centroid(mesh, mesh.hexes[h]));
    return w;
}
std::vector<Vec3> quadWhere(const HexMesh& mesh, const Topology& topo, const Found& f) {
    std::vector<Vec3> w;
    for (Index q : f.smallest) w.push_back(centroid(mesh, topo.quads[q].nodes));
    return w;
}
std::vector<Vec3> edgeWhere(const HexMesh& mesh, const Topology& topo, const Found& f) {
    std::vector<Vec3> w;
    for (Index e : f.smallest) w.push_back(centroid(mesh, topo.edges[e]));
    return w;
}
std::vector<Vec3> nodeWhere(const HexMesh& mesh, const Found& f) {
    std::vector<Vec3> w;
    for (Index v : f.smallest) w.push_back(mesh.nodes[v]);
    return w;
}

// What the checks through quadHexesAll find (hexes, quad orientation,
// overfull quads, unused nodes) ...
struct VolumeChecks {
    HexAcc hexes;
    Found orientation, overfull, unused;
};
// ... and what the surface checks through hexEdges find.
struct SurfaceChecks {
    SurfaceAcc fans;
    Found quadDoublets, coincident;
};

VolumeChecks checkVolume(const HexMesh& mesh, const Topology& topo) {
    VolumeChecks c{checkHexes(mesh, topo), checkOrientation(mesh, topo), {}, {}};
    for (Index q : topo.overfullQuads) c.overfull.add(q);
    c.unused = parallel::reduceOver<Found>(mesh.nodes.size(), 8192, [&](const auto& r, Found& acc) {
        for (std::size_t v = r.begin(); v != r.end(); ++v)
            if (topo.nodeHexes.size(v) == 0) acc.add(static_cast<Index>(v));
    });
    return c;
}

SurfaceChecks checkSurfaces(const HexMesh& mesh, const Topology& topo) {
    const SurfaceIndex surfaces = indexSurfaces(mesh, topo);
    return {checkSurfaceFans(mesh, topo, surfaces), checkQuadDoublets(topo, surfaces), checkCoincidentNodes(mesh, topo)};
}

void requireMaterials(const HexMesh& mesh) {
    if (mesh.material.size() != mesh.hexes.size())
        throw Error("validate: the mesh has " + std::to_string(mesh.hexes.size()) + " hexes but " +
                    std::to_string(mesh.material.size()) + " material ids; give every hex a material");
}

// The report of both; the places are read from the quads, edges and nodes.
ValidityReport assemble(const HexMesh& mesh, const Topology& topo, const VolumeChecks& volume,
                        const SurfaceChecks& surface) {
    const HexAcc& hexes = volume.hexes;
    const Found &orientation = volume.orientation, &overfull = volume.overfull, &unused = volume.unused;
    const SurfaceAcc& fans = surface.fans;
    const Found &quadDoublets = surface.quadDoublets, &coincident = surface.coincident;
    ValidityReport rep;
    put(rep, "repeated_node", "B,D,G", "hex", "hex uses the same node more than once (collapsed edge or face)",
        hexes.repeated, hexWhere(mesh, hexes.repeated));
    put(rep, "overfull_quad", "H", "quad", "quadrilateral shared by more than two hexes", overfull,
        quadWhere(mesh, topo, overfull));
    put(rep, "duplicate_hex", "I", "hex", "hex has the same eight nodes as a lower-numbered hex",
        hexes.duplicate, hexWhere(mesh, hexes.duplicate));
    put(rep, "hex_doublet", "I", "hex", "hex shares two or more quadrilaterals with another hex (doublet)",
        hexes.doublet, hexWhere(mesh, hexes.doublet));
    put(rep, "quad_doublet", "E", "quad",
        "surface quadrilateral shares two or more edges with another surface quadrilateral", quadDoublets,
        quadWhere(mesh, topo, quadDoublets));
    put(rep, "nonmanifold_edge", "K", "edge",
        "surface edge that is not bounded by exactly two quadrilaterals of one surface", fans.edges,
        edgeWhere(mesh, topo, fans.edges));
    put(rep, "nonmanifold_node", "K", "node",
        "surface quadrilaterals around the node form more than one fan (a pinch)", fans.nodes,
        nodeWhere(mesh, fans.nodes));
    put(rep, "inconsistent_orientation", "N", "quad",
        "both hexes on the quadrilateral see it with the same orientation (the mesh folds over itself)",
        orientation, quadWhere(mesh, topo, orientation));
    put(rep, "inverted_hex", "N", "hex", "hex with a corner or centre Jacobian determinant <= 0", hexes.inverted,
        hexWhere(mesh, hexes.inverted));
    put(rep, "unused_node", "A", "node", "node used by no hex", unused, nodeWhere(mesh, unused));
    put(rep, "coincident_node", "-", "node",
        "boundary node at the same place as another node it is not merged with: the hexes there are disconnected "
        "(duplicated, unmerged nodes; merge coincident nodes in the tool that wrote the mesh)",
        coincident, nodeWhere(mesh, coincident));
    return rep;
}

}  // namespace

// The quad holders and the per-hex edge ids are the topology's two largest
// parts after the quads, and the checks need them one after the other: each
// is built, used and dropped in turn (on 2 M hexes 70 MB less at the job's
// peak than the full topology), and each once.
ValidityReport validate(const HexMesh& mesh) {
    Topology topo = buildTopology(mesh, TopologyParts::QuadHolders);
    requireMaterials(mesh);
    const VolumeChecks volume = checkVolume(mesh, topo);
    topo.quadHexesAll = {};
    addHexEdges(topo, mesh);
    return assemble(mesh, topo, volume, checkSurfaces(mesh, topo));
}

ValidityReport validate(const HexMesh& mesh, const Topology& topo) {
    requireMaterials(mesh);
    requireTopologyOf(mesh, topo, "validate", TopologyParts::All);
    return assemble(mesh, topo, checkVolume(mesh, topo), checkSurfaces(mesh, topo));
}

nlohmann::json toJson(const ValidityReport& r) {
    nlohmann::json defects = nlohmann::json::object();
    for (const auto& [key, d] : r.defects) {
        nlohmann::json where = nlohmann::json::array();
        for (const Vec3& p : d.where) where.push_back({p[0], p[1], p[2]});
        defects[key] = {{"constraint", d.constraint}, {"description", d.description}, {"count", d.count},
                        {"entity", d.entity},         {"examples", d.examples},       {"where", where}};
    }
    return {{"ok", r.ok()}, {"defects", defects}};
}

}  // namespace isohex

#include "isohex/core/Validate.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "FaceLinks.hpp"
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

// ---------------------------------------------------------------- quad ids

// Quad ids as buildTopology numbers them without building the quads: each
// quad is owned by its smallest hex, and ids run in owner order, then local
// face order. `owned[h]` has bit f set where hex h owns face f.
struct QuadIds {
    std::vector<std::uint8_t> owned;
    std::vector<Index> base;  // base[h]: the first id of hex h's quads

    void number() {
        base.assign(owned.size() + 1, 0);
        for (std::size_t h = 0; h < owned.size(); ++h) base[h + 1] = base[h] + std::popcount(owned[h]);
    }
    Index id(Index h, int f) const {
        return base[h] + std::popcount(static_cast<unsigned>(owned[h] & ((1u << f) - 1u)));
    }
    std::array<Index, 2> face(Index id) const {  // (owner hex, local face)
        const auto h = static_cast<Index>(std::upper_bound(base.begin(), base.end(), id) - base.begin() - 1);
        unsigned bits = owned[h];
        for (Index k = id - base[h]; k > 0; --k) bits &= bits - 1;  // drop the owned faces before it
        return {h, std::countr_zero(bits)};
    }
};

// Every other hex holding each face of a hex, and the quad each face is: its
// owner (the smallest holder) and the owner's local face.
struct HexFaceHolders {
    std::array<int, 6> n;
    std::array<std::array<Index, detail::kMaxHolders>, 6> hex;
    std::array<std::array<std::int8_t, detail::kMaxHolders>, 6> face;
    std::array<std::int64_t, 6> quad;  // 6 * owner + owner's face
    std::uint8_t owned = 0;

    HexFaceHolders(const Csr& nodeHexes, const std::vector<Hex>& hexes, std::size_t h) {
        for (int f = 0; f < 6; ++f) {
            n[f] = detail::otherHolders(nodeHexes, hexes, h, f, hex[f], face[f]);
            const bool mine = n[f] == 0 || hex[f][0] > static_cast<Index>(h);
            if (mine) owned |= static_cast<std::uint8_t>(1u << f);
            quad[f] = mine ? 6 * std::int64_t(h) + f : 6 * std::int64_t(hex[f][0]) + face[f][0];
        }
    }
};

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

// Duplicate of a smaller hex: every candidate uses the smallest node, and
// must also use the largest one before the full comparison.
bool duplicatesSmaller(const HexMesh& mesh, const Csr& nodeHexes, Index h, const std::array<Index, 8>& key) {
    const Index lo = key.front(), hiNode = key.back();
    for (const Index* g = nodeHexes.begin(lo); g != nodeHexes.end(lo); ++g) {
        if (*g >= h) continue;
        const Hex& other = mesh.hexes[*g];
        if (std::find(other.begin(), other.end(), hiNode) == other.end()) continue;
        if (sortedNodes(other) == key) return true;
    }
    return false;
}

// Doublet: one neighbour reached through two different quads. Identical
// hexes share all their quads; they are reported as duplicates.
bool inDoublet(const HexMesh& mesh, Index h, const HexFaceHolders& fh) {
    std::array<std::pair<Index, std::int64_t>, 24> seen;  // (neighbour hex, quad)
    int nSeen = 0;
    for (int f = 0; f < 6; ++f)
        for (int k = 0; k < fh.n[f]; ++k) {
            const Index g = fh.hex[f][k];
            for (int s = 0; s < nSeen; ++s)
                if (seen[s].first == g && seen[s].second != fh.quad[f] && !sameNodeSet(mesh, h, g)) return true;
            if (nSeen < static_cast<int>(seen.size())) seen[nSeen++] = {g, fh.quad[f]};
        }
    return false;
}

// Two hexes on opposite sides of a quad traverse it in opposite directions. If
// both traverse it the same way, one of them lies folded onto the other.
bool misoriented(const HexMesh& mesh, Index h0, int f0, Index h1, int f1) {
    if (detail::hasRepeatedNode(mesh.hexes[h0]) || detail::hasRepeatedNode(mesh.hexes[h1])) return false;
    const auto a = faceNodes(mesh, h0, f0);
    const auto b = faceNodes(mesh, h1, f1);
    const auto k = std::find(b.begin(), b.end(), a[0]) - b.begin();
    if (k == 4) return false;
    const bool same = b[(k + 1) % 4] == a[1] && b[(k + 3) % 4] == a[3];
    return same && !sameNodeSet(mesh, h0, h1);
}

// What the pass over the hexes finds: per hex, and for the quads each hex
// owns (as owner hex and face; ids once every hex's owned faces are known),
// with the surface quads the surface checks read.
struct VolumeAcc {
    HexAcc hexes;
    std::vector<std::array<Index, 2>> misoriented, overfull;
    std::vector<Quad> surface;
    void merge(const VolumeAcc& o) {
        hexes.merge(o.hexes);
        misoriented.insert(misoriented.end(), o.misoriented.begin(), o.misoriented.end());
        overfull.insert(overfull.end(), o.overfull.begin(), o.overfull.end());
        surface.insert(surface.end(), o.surface.begin(), o.surface.end());
    }
};

// One pass over the hexes: a hex's own checks, and each quad's (overfull,
// orientation, on a surface) at its owner. Fills ids.owned.
VolumeAcc scanHexes(const HexMesh& mesh, const Csr& nodeHexes, QuadIds& ids) {
    ids.owned.assign(mesh.hexes.size(), 0);
    return parallel::reduceOver<VolumeAcc>(mesh.hexes.size(), 1024, [&](const auto& r, VolumeAcc& acc) {
        for (std::size_t hi = r.begin(); hi != r.end(); ++hi) {
            const Index h = static_cast<Index>(hi);
            const auto key = sortedNodes(mesh.hexes[hi]);
            const bool repeated = std::adjacent_find(key.begin(), key.end()) != key.end();
            if (repeated) acc.hexes.repeated.add(h);
            if (duplicatesSmaller(mesh, nodeHexes, h, key)) acc.hexes.duplicate.add(h);
            const HexFaceHolders fh(nodeHexes, mesh.hexes, hi);
            ids.owned[hi] = fh.owned;
            if (inDoublet(mesh, h, fh)) acc.hexes.doublet.add(h);
            for (int f = 0; f < 6; ++f) {
                if (!(fh.owned >> f & 1)) continue;
                const int holders = 1 + fh.n[f] + (repeated ? detail::selfHolds(mesh.hexes[hi], f) : 0);
                const Index other = fh.n[f] > 0 ? fh.hex[f][0] : kNone;
                const std::int8_t otherFace = fh.n[f] > 0 ? fh.face[f][0] : std::int8_t(-1);
                if (holders > 2) acc.overfull.push_back({h, f});
                else if (holders == 2 && fh.n[f] == 1 && misoriented(mesh, h, f, other, otherFace))
                    acc.misoriented.push_back({h, f});
                if (auto quad = detail::surfaceQuad(mesh, hi, f, holders, other, otherFace))
                    acc.surface.push_back(*quad);
            }
            // A hex with a repeated node has zero determinants by construction;
            // it is reported once, as repeated_node. NaN counts as inverted.
            if (!repeated && !(minJacobianDeterminant(hexCoords(mesh, h)) > 0.0)) acc.hexes.inverted.add(h);
        }
    });
}

// ---------------------------------------------------------------- surfaces

// The quads of every surface patch, numbered consecutively patch by patch
// ("surface quads"), and for every node the surface quads that contain it.
struct SurfaceIndex {
    std::vector<Index> quad;     // surface quad -> quad of the surface topology
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

// An edge (a, b) with a hex known to hold it.
using HeldEdge = std::array<Index, 3>;

struct SurfaceAcc {
    Found nodes;
    std::vector<HeldEdge> edges;
    void merge(const SurfaceAcc& o) {
        nodes.merge(o.nodes);
        edges.insert(edges.end(), o.edges.begin(), o.edges.end());
    }
};
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
                // The first surface quad at v on edge (v, w) whose hex has the edge.
                for (Index sq : row) {
                    const Quad& quad = topo.quads[s.quad[sq]];
                    if (std::find(quad.nodes.begin(), quad.nodes.end(), w) != quad.nodes.end() &&
                        detail::localEdgeWith(mesh.hexes[quad.hex[0]], v, w) >= 0) {
                        acc.edges.push_back({v, w, quad.hex[0]});
                        break;
                    }
                }
            }
        }
    });
}

// Two surface quads (of any surfaces) sharing two or more edges; found by
// their ids among all quads.
Found checkQuadDoublets(const Topology& topo, const SurfaceIndex& s, const QuadIds& ids) {
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
            if (doublet) acc.add(ids.id(topo.quads[q].hex[0], topo.quads[q].localFace[0]));
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
std::vector<Vec3> quadWhere(const HexMesh& mesh, const QuadIds& ids, const Found& f) {
    std::vector<Vec3> w;
    for (Index q : f.smallest) {
        const auto [h, face] = ids.face(q);
        w.push_back(centroid(mesh, faceNodes(mesh, h, face)));
    }
    return w;
}
std::vector<Vec3> nodeWhere(const HexMesh& mesh, const Found& f) {
    std::vector<Vec3> w;
    for (Index v : f.smallest) w.push_back(mesh.nodes[v]);
    return w;
}

// The flagged edges as buildTopology numbers them (owner order, then local
// edge order), with their places; the owned edges of every hex are counted
// only when an edge was flagged.
struct EdgeFindings {
    Found found;
    std::vector<Vec3> where;
};

EdgeFindings idsOfFlaggedEdges(const HexMesh& mesh, const Csr& nodeHexes, std::vector<HeldEdge> edges) {
    EdgeFindings out;
    if (edges.empty()) return out;
    const std::size_t H = mesh.hexes.size();
    std::vector<std::uint16_t> bits(H);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H, 1024), [&](const auto& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h) bits[h] = detail::ownedEdgeBits(nodeHexes, mesh.hexes, h);
    });
    std::vector<Index> base(H + 1, 0);
    for (std::size_t h = 0; h < H; ++h) base[h + 1] = base[h] + std::popcount(bits[h]);
    std::vector<std::pair<Index, std::array<Index, 2>>> byId;
    for (const auto& [a, b, holder] : edges) {
        const Index owner = detail::smallestHolder(nodeHexes, mesh.hexes, a, b, holder);
        const int e = detail::localEdgeWith(mesh.hexes[owner], a, b);
        const Index id = base[owner] + std::popcount(static_cast<unsigned>(bits[owner] & ((1u << e) - 1u)));
        out.found.add(id);
        byId.push_back({id, {std::min(a, b), std::max(a, b)}});
    }
    std::sort(byId.begin(), byId.end());
    for (Index id : out.found.smallest)
        out.where.push_back(centroid(mesh, std::lower_bound(byId.begin(), byId.end(), std::make_pair(id, std::array<Index, 2>{}))->second));
    return out;
}

// What the pass over the hexes finds, with quad ids ...
struct VolumeChecks {
    HexAcc hexes;
    Found orientation, overfull, unused;
};
// ... and what the surface checks find.
struct SurfaceChecks {
    Found pinched, quadDoublets, coincident;
    EdgeFindings nonmanifoldEdges;
};

// The volume's checks; `surfaces` gets the node rows it is given and the
// surface quads, in owner order, as buildTopology(mesh, Surfaces) has them.
VolumeChecks checkVolume(const HexMesh& mesh, Topology& surfaces, QuadIds& ids) {
    const Csr& nodeHexes = surfaces.nodeHexes;
    VolumeAcc acc = scanHexes(mesh, nodeHexes, ids);
    std::sort(acc.surface.begin(), acc.surface.end(), [](const Quad& a, const Quad& b) {
        return std::pair(a.hex[0], a.localFace[0]) < std::pair(b.hex[0], b.localFace[0]);
    });
    detail::setSurfaceQuads(surfaces, mesh, std::move(acc.surface));
    ids.number();
    VolumeChecks c{acc.hexes, {}, {}, {}};
    for (const auto& [h, f] : acc.misoriented) c.orientation.add(ids.id(h, f));
    for (const auto& [h, f] : acc.overfull) c.overfull.add(ids.id(h, f));
    c.unused = parallel::reduceOver<Found>(mesh.nodes.size(), 8192, [&](const auto& r, Found& found) {
        for (std::size_t v = r.begin(); v != r.end(); ++v)
            if (nodeHexes.size(v) == 0) found.add(static_cast<Index>(v));
    });
    return c;
}

SurfaceChecks checkSurfaces(const HexMesh& mesh, const Topology& topo, const QuadIds& ids) {
    const SurfaceIndex surfaces = indexSurfaces(mesh, topo);
    SurfaceAcc fans = checkSurfaceFans(mesh, topo, surfaces);
    return {fans.nodes, checkQuadDoublets(topo, surfaces, ids), checkCoincidentNodes(mesh, topo),
            idsOfFlaggedEdges(mesh, topo.nodeHexes, std::move(fans.edges))};
}

void requireMaterials(const HexMesh& mesh) {
    if (mesh.material.size() != mesh.hexes.size())
        throw Error("validate: the mesh has " + std::to_string(mesh.hexes.size()) + " hexes but " +
                    std::to_string(mesh.material.size()) + " material ids; give every hex a material");
}

// The report of both; the places are read from the hexes' faces, the edges'
// ends and the nodes.
ValidityReport assemble(const HexMesh& mesh, const QuadIds& ids, const VolumeChecks& volume,
                        const SurfaceChecks& surface) {
    const HexAcc& hexes = volume.hexes;
    const Found &orientation = volume.orientation, &overfull = volume.overfull, &unused = volume.unused;
    const Found &quadDoublets = surface.quadDoublets, &coincident = surface.coincident;
    ValidityReport rep;
    put(rep, "repeated_node", "B,D,G", "hex", "hex uses the same node more than once (collapsed edge or face)",
        hexes.repeated, hexWhere(mesh, hexes.repeated));
    put(rep, "overfull_quad", "H", "quad", "quadrilateral shared by more than two hexes", overfull,
        quadWhere(mesh, ids, overfull));
    put(rep, "duplicate_hex", "I", "hex", "hex has the same eight nodes as a lower-numbered hex",
        hexes.duplicate, hexWhere(mesh, hexes.duplicate));
    put(rep, "hex_doublet", "I", "hex", "hex shares two or more quadrilaterals with another hex (doublet)",
        hexes.doublet, hexWhere(mesh, hexes.doublet));
    put(rep, "quad_doublet", "E", "quad",
        "surface quadrilateral shares two or more edges with another surface quadrilateral", quadDoublets,
        quadWhere(mesh, ids, quadDoublets));
    put(rep, "nonmanifold_edge", "K", "edge",
        "surface edge that is not bounded by exactly two quadrilaterals of one surface", surface.nonmanifoldEdges.found,
        surface.nonmanifoldEdges.where);
    put(rep, "nonmanifold_node", "K", "node",
        "surface quadrilaterals around the node form more than one fan (a pinch)", surface.pinched,
        nodeWhere(mesh, surface.pinched));
    put(rep, "inconsistent_orientation", "N", "quad",
        "both hexes on the quadrilateral see it with the same orientation (the mesh folds over itself)",
        orientation, quadWhere(mesh, ids, orientation));
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

// Only the node-to-hex rows and the surface quads are kept (what
// buildTopology(mesh, TopologyParts::Surfaces) gives, collected by the one
// pass over the hexes); every face's holders are found from the rows as the
// pass reaches it, and quad and edge ids are those buildTopology gives,
// counted from the faces and edges each hex owns. On 2 M hexes this holds
// about 45 bytes per hex where the full topology held 220.
ValidityReport validate(const HexMesh& mesh) {
    requireMaterials(mesh);
    detail::checkIndices(mesh);
    Topology topo;
    topo.nodeHexes = detail::nodeHexRows(mesh.hexes, mesh.nodes.size());
    QuadIds ids;
    const VolumeChecks volume = checkVolume(mesh, topo, ids);
    return assemble(mesh, ids, volume, checkSurfaces(mesh, topo, ids));
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

#include "isohex/core/Topology.hpp"

#include <algorithm>
#include <bit>
#include <limits>
#include <map>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/core/Parallel.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"
#include "FaceLinks.hpp"

namespace isohex {

using namespace detail;  // FaceLinks.hpp

namespace {

// The part of requireTopologyOf every topology meets: built for this mesh.
void requireBuiltFor(const HexMesh& mesh, const Topology& topo, const std::string& who) {
    if (topo.hexQuads.size() != mesh.hexes.size() || topo.nodeHexes.rows() != mesh.nodes.size() ||
        topo.nodeOnBoundary.size() != mesh.nodes.size())
        throw Error(who + ": the topology was built for a different mesh (" + std::to_string(topo.hexQuads.size()) +
                    " hexes, " + std::to_string(topo.nodeHexes.rows()) + " nodes; this mesh has " +
                    std::to_string(mesh.hexes.size()) + " and " + std::to_string(mesh.nodes.size()) +
                    "); rebuild it with buildTopology()");
}

}  // namespace

void requireTopologyOf(const HexMesh& mesh, const Topology& topo, const std::string& who, TopologyParts parts) {
    requireBuiltFor(mesh, topo, who);
    const bool edges = parts != TopologyParts::QuadHolders, holders = parts != TopologyParts::NodeMoves;
    if (edges && !mesh.hexes.empty() && topo.edges.empty())
        throw Error(who + ": needs a topology with its edges; build it with buildTopology(mesh) or add them "
                          "with addHexEdges");
    if (parts == TopologyParts::All && topo.hexEdges.size() != mesh.hexes.size())
        throw Error(who + ": needs a topology with every part; build it with buildTopology(mesh)");
    if (holders && topo.quadHexesAll.rows() != topo.quads.size())
        throw Error(who + ": needs a topology with the quads' holders; build it with buildTopology(mesh)");
}

namespace {

using Range = tbb::blocked_range<std::size_t>;

// Links every hex face to the other hexes holding it. quadBase[h + 1] gets
// the number of faces hex h owns.
std::vector<FaceLink> linkFaces(const Csr& nodeHexes, const std::vector<Hex>& hexes, std::vector<Index>& quadBase) {
    const std::size_t H = hexes.size();
    std::vector<FaceLink> link(H);
    quadBase.assign(H + 1, 0);
    tbb::parallel_for(Range(0, H, 1024), [&](const Range& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h) {
            const bool repeats = hasRepeatedNode(hexes[h]);
            Index owned = 0;
            for (int f = 0; f < 6; ++f) {
                linkFace(nodeHexes, hexes, h, f, repeats, link[h]);
                if (link[h].owned(h, f)) ++owned;
            }
            quadBase[h + 1] = owned;
        }
    });
    return link;
}

// quad -> every hex holding it, from the per-quad holder counts (shifted by
// one); in hex order, so each row comes out sorted.
void listQuadHolders(Topology& t, std::size_t H, std::vector<Index> holderCount) {
    const std::size_t Q = t.quads.size();
    for (std::size_t q = 0; q < Q; ++q) holderCount[q + 1] += holderCount[q];
    t.quadHexesAll.offsets = std::move(holderCount);
    t.quadHexesAll.items.assign(static_cast<std::size_t>(t.quadHexesAll.offsets[Q]), kNone);
    std::vector<Index> fill(t.quadHexesAll.offsets.begin(), t.quadHexesAll.offsets.end() - 1);
    for (std::size_t h = 0; h < H; ++h)
        for (int f = 0; f < 6; ++f) {
            const Index q = t.hexQuads[h][f];
            if (fill[q] < t.quadHexesAll.offsets[q + 1]) t.quadHexesAll.items[fill[q]++] = static_cast<Index>(h);
        }
}

// Numbers the quads: each is owned by its smallest hex and numbered in owner
// order (independent of the thread count); faces a hex does not own take the
// id of the owner's face. Returns how many hexes hold each quad, shifted by
// one (holderCount[q + 1]).
std::vector<Index> numberQuads(Topology& t, const std::vector<Hex>& hexes) {
    const std::size_t H = hexes.size();
    t.hexQuads.resize(H);
    std::vector<Index> quadBase;
    std::vector<FaceLink> link = linkFaces(t.nodeHexes, hexes, quadBase);
    for (std::size_t h = 0; h < H; ++h) quadBase[h + 1] += quadBase[h];
    const std::size_t Q = quadBase[H];
    t.quads.resize(Q);
    std::vector<Index> holderCount(Q + 1, 0);
    tbb::parallel_for(Range(0, H, 1024), [&](const Range& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h) {
            Index q = quadBase[h];
            for (int f = 0; f < 6; ++f) {
                if (!link[h].owned(h, f)) continue;
                const auto& lf = hexcell::kFaces[f];
                Quad& quad = t.quads[q];
                for (int i = 0; i < 4; ++i) quad.nodes[i] = hexes[h][lf[i]];
                quad.hex[0] = static_cast<Index>(h);
                quad.localFace[0] = static_cast<std::int8_t>(f);
                quad.hex[1] = link[h].other[f];
                quad.localFace[1] = link[h].otherFace[f];
                holderCount[q + 1] = link[h].holders[f];
                t.hexQuads[h][f] = q++;
            }
        }
    });
    tbb::parallel_for(Range(0, H, 1024), [&](const Range& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h)
            for (int f = 0; f < 6; ++f)
                if (!link[h].owned(h, f)) t.hexQuads[h][f] = t.hexQuads[link[h].other[f]][link[h].otherFace[f]];
    });
    return holderCount;
}

// Numbers the edges: an edge is held by the hexes holding both its ends and
// owned by the smallest, within it by the first local edge with these ends;
// numbered in owner order, the others take the owner's id (in hexEdges, when
// `perHex`).
void numberEdges(Topology& t, const std::vector<Hex>& hexes, bool perHex) {
    const std::size_t H = hexes.size();
    if (perHex) t.hexEdges.resize(H);
    // With perHex, an edge's entry first holds its owner hex where another
    // hex owns it, and the owner's edge id after the last pass.
    std::vector<std::uint16_t> ownedEdges(H, 0);
    std::vector<Index> edgeBase(H + 1, 0);
    tbb::parallel_for(Range(0, H, 1024), [&](const Range& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h) {
            const std::uint16_t bits = ownedEdgeBits(t.nodeHexes, hexes, h);
            if (perHex)
                for (int e = 0; e < 12; ++e)
                    if (!(bits >> e & 1)) {
                        const Index a = hexes[h][hexcell::kEdges[e][0]], b = hexes[h][hexcell::kEdges[e][1]];
                        t.hexEdges[h][e] = smallestHolder(t.nodeHexes, hexes, a, b, static_cast<Index>(h));
                    }
            ownedEdges[h] = bits;
            edgeBase[h + 1] = static_cast<Index>(std::popcount(bits));
        }
    });
    for (std::size_t h = 0; h < H; ++h) edgeBase[h + 1] += edgeBase[h];
    t.edges.resize(edgeBase[H]);
    tbb::parallel_for(Range(0, H, 1024), [&](const Range& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h) {
            Index id = edgeBase[h];
            for (int e = 0; e < 12; ++e)
                if (ownedEdges[h] >> e & 1) {
                    const Index a = hexes[h][hexcell::kEdges[e][0]], b = hexes[h][hexcell::kEdges[e][1]];
                    t.edges[id] = {std::min(a, b), std::max(a, b)};
                    if (perHex) t.hexEdges[h][e] = id;
                    ++id;
                }
        }
    });
    if (!perHex) return;
    // Owned entries hold ids by now and are only read here; each hex writes
    // only its own entries that another hex owns.
    tbb::parallel_for(Range(0, H, 1024), [&](const Range& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h)
            for (int e = 0; e < 12; ++e) {
                if (ownedEdges[h] >> e & 1) continue;
                const Index a = hexes[h][hexcell::kEdges[e][0]], b = hexes[h][hexcell::kEdges[e][1]];
                const Index owner = t.hexEdges[h][e];
                t.hexEdges[h][e] = t.hexEdges[owner][localEdgeWith(hexes[owner], a, b)];
            }
    });
}

// TopologyParts::Surfaces: only the quads on a boundary (one holder) or an
// interface (two holders of different material), each from its owner, in
// owner order: the ids the same quads have among all quads, renumbered
// without the others. Per-range lists joined in range order, so the order is
// the same for any thread count; no per-hex array is kept.
void numberSurfaceQuads(Topology& t, const HexMesh& mesh) {
    const std::vector<Hex>& hexes = mesh.hexes;
    const std::size_t H = hexes.size();
    constexpr std::size_t kRange = 4096;
    std::vector<std::vector<Quad>> found((H + kRange - 1) / kRange);
    tbb::parallel_for(std::size_t(0), found.size(), [&](std::size_t k) {
        FaceLink L;
        for (std::size_t h = k * kRange; h < std::min(H, (k + 1) * kRange); ++h) {
            const bool repeats = hasRepeatedNode(hexes[h]);
            for (int f = 0; f < 6; ++f) {
                linkFace(t.nodeHexes, hexes, h, f, repeats, L);
                if (auto quad = surfaceQuad(mesh, h, f, L.holders[f], L.other[f], L.otherFace[f]))
                    found[k].push_back(*quad);
            }
        }
    });
    std::vector<Quad> quads;
    for (const std::vector<Quad>& list : found) quads.insert(quads.end(), list.begin(), list.end());
    setSurfaceQuads(t, mesh, std::move(quads));
}

// Sorts the quads into boundary (one hex), interface (two of different
// material) and overfull (more than two) by their holder counts (shifted by
// one, as numberQuads gives them), and marks the boundary nodes.
void classifyQuads(Topology& t, const HexMesh& mesh, const std::vector<Index>& holderCount) {
    t.nodeOnBoundary.assign(mesh.nodes.size(), 0);
    for (std::size_t q = 0; q < t.quads.size(); ++q) {
        const auto n = holderCount[q + 1];
        const Quad& quad = t.quads[q];
        if (n == 1) {
            t.boundaryQuads.push_back(static_cast<Index>(q));
            for (Index v : quad.nodes) t.nodeOnBoundary[v] = 1;
        } else if (n == 2) {
            if (quad.hex[1] != kNone && mesh.material[quad.hex[0]] != mesh.material[quad.hex[1]])
                t.interfaceQuads.push_back(static_cast<Index>(q));
        } else {
            t.overfullQuads.push_back(static_cast<Index>(q));
        }
    }
    for (std::size_t v = 0; v < mesh.nodes.size(); ++v)
        if (t.nodeOnBoundary[v]) t.boundaryNodes.push_back(static_cast<Index>(v));
}

}  // namespace

Topology buildTopology(const HexMesh& mesh, TopologyParts parts) {
    checkIndices(mesh);
    const bool all = parts == TopologyParts::All;
    Topology t;
    t.nodeHexes = nodeHexRows(mesh.hexes, mesh.nodes.size());
    if (parts == TopologyParts::Surfaces || parts == TopologyParts::SurfaceMoves) {
        numberSurfaceQuads(t, mesh);
        if (parts == TopologyParts::SurfaceMoves) numberEdges(t, mesh.hexes, false);
        return t;
    }
    std::vector<Index> holderCount = numberQuads(t, mesh.hexes);
    classifyQuads(t, mesh, holderCount);
    if (parts != TopologyParts::NodeMoves) listQuadHolders(t, mesh.hexes.size(), std::move(holderCount));
    holderCount = {};
    if (parts != TopologyParts::QuadHolders) numberEdges(t, mesh.hexes, all);
    return t;
}

void addQuadHolders(Topology& t, const HexMesh& mesh) {
    requireBuiltFor(mesh, t, "addQuadHolders");
    const std::size_t H = mesh.hexes.size();
    std::vector<Index> quadBase;
    std::vector<FaceLink> link = linkFaces(t.nodeHexes, mesh.hexes, quadBase);
    for (std::size_t h = 0; h < H; ++h) quadBase[h + 1] += quadBase[h];
    std::vector<Index> holderCount(t.quads.size() + 1, 0);
    tbb::parallel_for(Range(0, H, 1024), [&](const Range& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h) {
            Index q = quadBase[h];
            for (int f = 0; f < 6; ++f)
                if (link[h].owned(h, f)) holderCount[static_cast<std::size_t>(q++) + 1] = link[h].holders[f];
        }
    });
    link = {};
    listQuadHolders(t, H, std::move(holderCount));
}

void addHexEdges(Topology& t, const HexMesh& mesh) {
    requireBuiltFor(mesh, t, "addHexEdges");
    numberEdges(t, mesh.hexes, true);
}

Index edgeBetween(const HexMesh& mesh, const Topology& topo, Index a, Index b) {
    if (topo.hexEdges.size() != mesh.hexes.size())
        throw Error("edgeBetween needs a topology with hexEdges (built with TopologyParts::All)");
    if (a < 0 || b < 0 || static_cast<std::size_t>(std::max(a, b)) >= topo.nodeHexes.rows()) return kNone;
    std::array<Index, kMaxHolders> cand;
    const int n = intersectRows(topo.nodeHexes, a, b, cand);
    for (int c = 0; c < n; ++c) {
        const int e = localEdgeWith(mesh.hexes[cand[c]], a, b);
        if (e >= 0) return topo.hexEdges[cand[c]][e];
    }
    return kNone;
}

std::vector<SurfacePatch> surfacePatches(const HexMesh& mesh, const Topology& topo) {
    std::map<std::pair<std::int32_t, std::int32_t>, SurfacePatch> byTag;
    for (Index q : topo.boundaryQuads) {
        const Quad& quad = topo.quads[q];
        const std::int32_t m = mesh.material[quad.hex[0]];
        SurfacePatch& p = byTag[{m, -1}];
        p.tag.inside = m;
        p.tag.outside = -1;
        p.quads.push_back(q);
        p.hexFaces.emplace_back(quad.hex[0], quad.localFace[0]);
    }
    for (Index q : topo.interfaceQuads) {
        const Quad& quad = topo.quads[q];
        const std::int32_t a = mesh.material[quad.hex[0]], b = mesh.material[quad.hex[1]];
        const int side = a < b ? 0 : 1;
        SurfacePatch& p = byTag[{std::min(a, b), std::max(a, b)}];
        p.tag.inside = std::min(a, b);
        p.tag.outside = std::max(a, b);
        p.quads.push_back(q);
        p.hexFaces.emplace_back(quad.hex[side], quad.localFace[side]);
    }
    std::vector<SurfacePatch> out;
    out.reserve(byTag.size());
    for (auto& [key, patch] : byTag) {
        // Keep a name the mesh already gave this surface.
        for (const SurfaceTag& s : mesh.surfaces)
            if (s.inside == patch.tag.inside && s.outside == patch.tag.outside) patch.tag.name = s.name;
        out.push_back(std::move(patch));
    }
    return out;
}

}  // namespace isohex

namespace isohex {

void classifyBoundaryNodes(HexMesh& mesh) {
    const Topology topo = buildTopology(mesh);
    const std::vector<SurfacePatch> patches = surfacePatches(mesh, topo);
    mesh.surfaces.clear();
    mesh.curves.clear();
    std::vector<std::int32_t> first(mesh.nodeCount(), -1);
    std::vector<std::uint8_t> many(mesh.nodeCount(), 0);
    for (std::size_t s = 0; s < patches.size(); ++s) {
        mesh.surfaces.push_back(patches[s].tag);
        for (Index q : patches[s].quads)
            for (Index v : topo.quads[q].nodes) {
                if (first[v] < 0) first[v] = static_cast<std::int32_t>(s);
                else if (first[v] != static_cast<std::int32_t>(s)) many[v] = 1;
            }
    }
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v) {
        if (mesh.nodeClass[v].kind == NodeKind::Fixed) continue;
        if (many[v]) mesh.nodeClass[v] = {NodeKind::Curve, -1};
        else if (first[v] >= 0) mesh.nodeClass[v] = {NodeKind::Surface, first[v]};
        else mesh.nodeClass[v] = {};
    }
}

}  // namespace isohex

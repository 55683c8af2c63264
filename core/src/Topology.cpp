#include "isohex/core/Topology.hpp"

#include <algorithm>
#include <limits>
#include <map>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "Parallel.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"

namespace isohex {

namespace {

using detail::bucketItems;

std::array<Index, 4> sortedFace(const Hex& h, int f) {
    std::array<Index, 4> k;
    for (int i = 0; i < 4; ++i) k[i] = h[hexcell::kFaces[f][i]];
    std::sort(k.begin(), k.end());
    return k;
}

void checkIndices(const HexMesh& mesh) {
    const auto n = static_cast<Index>(mesh.nodes.size());
    if (mesh.material.size() != mesh.hexes.size())
        throw Error("mesh has " + std::to_string(mesh.hexes.size()) + " hexes but " +
                    std::to_string(mesh.material.size()) + " material ids");
    if (mesh.hexes.size() * 12 > static_cast<std::size_t>(std::numeric_limits<Index>::max()))
        throw Error("mesh has " + std::to_string(mesh.hexes.size()) +
                    " hexes; topology is limited to 178 million hexes");
    for (std::size_t h = 0; h < mesh.hexes.size(); ++h)
        for (Index v : mesh.hexes[h])
            if (v < 0 || v >= n)
                throw Error("hex " + std::to_string(h) + " refers to node " + std::to_string(v) +
                            ", which does not exist (the mesh has " + std::to_string(n) + " nodes)");
}

// Groups the rows of `c` (items sorted by id) by a key per item and calls
// emit(row, firstPos, endPos, groupIndexInRow) for each group of equal keys.
// Rows are reordered in place: by key, ties by item id.
template <class KeyOf>
std::vector<Index> groupRows(Csr& c, KeyOf keyOf) {
    using Key = decltype(keyOf(Index{}));
    std::vector<Index> groups(c.rows() + 1, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, c.rows(), 512), [&](const auto& r) {
        std::vector<std::pair<Key, Index>> buf;
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            const Index lo = c.offsets[b], hi = c.offsets[b + 1];
            buf.clear();
            for (Index p = lo; p < hi; ++p) buf.emplace_back(keyOf(c.items[p]), c.items[p]);
            std::sort(buf.begin(), buf.end());
            Index count = 0;
            for (std::size_t i = 0; i < buf.size(); ++i) {
                c.items[lo + static_cast<Index>(i)] = buf[i].second;
                if (i == 0 || buf[i].first != buf[i - 1].first) ++count;
            }
            groups[b + 1] = count;
        }
    });
    for (std::size_t b = 0; b < c.rows(); ++b) groups[b + 1] += groups[b];
    return groups;  // groups[b] = id of the first group in row b
}

}  // namespace

Topology buildTopology(const HexMesh& mesh) {
    checkIndices(mesh);
    Topology t;
    const std::size_t H = mesh.hexes.size();
    const std::size_t N = mesh.nodes.size();
    const auto& hexes = mesh.hexes;

    // ---- quads: local face id = 6 * hex + f, bucketed under its smallest node
    auto faceMin = [&](std::size_t i) { return sortedFace(hexes[i / 6], static_cast<int>(i % 6))[0]; };
    Csr faces = bucketItems(N, H * 6, faceMin);
    auto faceKey = [&](Index i) { return sortedFace(hexes[i / 6], i % 6); };
    std::vector<Index> quadStart = groupRows(faces, faceKey);
    const std::size_t Q = quadStart.back();
    t.quads.resize(Q);
    t.hexQuads.resize(H);
    t.quadHexesAll.offsets.resize(Q + 1);
    t.quadHexesAll.items.resize(faces.items.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, N, 512), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index q = quadStart[b] - 1;
            std::array<Index, 4> prev{};
            for (Index p = faces.offsets[b]; p < faces.offsets[b + 1]; ++p) {
                const Index item = faces.items[p];
                const Index h = item / 6;
                const int f = item % 6;
                const auto key = sortedFace(hexes[h], f);
                t.quadHexesAll.items[p] = h;
                if (p == faces.offsets[b] || key != prev) {
                    ++q;
                    prev = key;
                    t.quadHexesAll.offsets[q] = p;
                    Quad& quad = t.quads[q];
                    for (int i = 0; i < 4; ++i) quad.nodes[i] = hexes[h][hexcell::kFaces[f][i]];
                    quad.hex[0] = h;
                    quad.localFace[0] = static_cast<std::int8_t>(f);
                } else if (t.quads[q].hex[1] == kNone) {
                    t.quads[q].hex[1] = h;
                    t.quads[q].localFace[1] = static_cast<std::int8_t>(f);
                }
                t.hexQuads[h][f] = q;
            }
        }
    });
    t.quadHexesAll.offsets[Q] = static_cast<Index>(faces.items.size());
    faces = Csr{};

    // ---- edges: local edge id = 12 * hex + e, bucketed under the smaller node
    auto edgeEnds = [&](std::size_t i) {
        const Hex& h = hexes[i / 12];
        const auto& e = hexcell::kEdges[i % 12];
        const Index a = h[e[0]], b = h[e[1]];
        return std::pair<Index, Index>(std::min(a, b), std::max(a, b));
    };
    Csr edgeItems = bucketItems(N, H * 12, [&](std::size_t i) { return edgeEnds(i).first; });
    std::vector<Index> edgeStart = groupRows(edgeItems, [&](Index i) { return edgeEnds(i).second; });
    const std::size_t E = edgeStart.back();
    t.edges.resize(E);
    t.hexEdges.resize(H);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, N, 512), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            Index e = edgeStart[b] - 1;
            Index prev = kNone;
            for (Index p = edgeItems.offsets[b]; p < edgeItems.offsets[b + 1]; ++p) {
                const Index item = edgeItems.items[p];
                const auto ends = edgeEnds(item);
                if (ends.second != prev) {
                    ++e;
                    prev = ends.second;
                    t.edges[e] = {ends.first, ends.second};
                }
                t.hexEdges[item / 12][item % 12] = e;
            }
        }
    });
    edgeItems = Csr{};

    // ---- node -> hexes
    t.nodeHexes = bucketItems(N, H * 8, [&](std::size_t i) { return hexes[i / 8][i % 8]; });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, t.nodeHexes.items.size(), 8192), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) t.nodeHexes.items[i] /= 8;
    });

    // ---- boundary, interfaces, invalid quads
    t.nodeOnBoundary.assign(N, 0);
    for (std::size_t q = 0; q < Q; ++q) {
        const auto n = t.quadHexesAll.size(q);
        const Quad& quad = t.quads[q];
        if (n == 1) {
            t.boundaryQuads.push_back(static_cast<Index>(q));
            for (Index v : quad.nodes) t.nodeOnBoundary[v] = 1;
        } else if (n == 2) {
            if (mesh.material[quad.hex[0]] != mesh.material[quad.hex[1]])
                t.interfaceQuads.push_back(static_cast<Index>(q));
        } else {
            t.overfullQuads.push_back(static_cast<Index>(q));
        }
    }
    for (std::size_t v = 0; v < N; ++v)
        if (t.nodeOnBoundary[v]) t.boundaryNodes.push_back(static_cast<Index>(v));
    return t;
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

#include "FaceLinks.hpp"

#include <algorithm>
#include <limits>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"
#include "isohex/core/Parallel.hpp"

namespace isohex::detail {

namespace {

// Face f as a bit mask of its corners: matchingFace works through these, no sorting.
constexpr std::array<std::uint8_t, 6> faceMasks() {
    std::array<std::uint8_t, 6> m{};
    for (int f = 0; f < 6; ++f)
        for (int c : hexcell::kFaces[f]) m[f] |= static_cast<std::uint8_t>(1u << c);
    return m;
}
constexpr std::array<std::uint8_t, 6> kFaceMask = faceMasks();

}  // namespace

std::array<Index, 4> sortedFace(const Hex& h, int f) {
    std::array<Index, 4> k;
    for (int i = 0; i < 4; ++i) k[i] = h[hexcell::kFaces[f][i]];
    std::sort(k.begin(), k.end());
    return k;
}

int matchingFace(const Hex& h, const Hex& g, int f) {
    unsigned mask = 0;
    for (int i = 0; i < 4; ++i) {
        const Index v = g[hexcell::kFaces[f][i]];
        unsigned bit = 0;
        for (int c = 0; c < 8; ++c)
            if (h[c] == v) {
                bit = 1u << c;
                break;
            }
        if (!bit) return -1;
        mask |= bit;
    }
    for (int k = 0; k < 6; ++k)
        if (kFaceMask[k] == mask) return k;
    return -1;
}

int localEdgeWith(const Hex& h, Index a, Index b) {
    for (int e = 0; e < 12; ++e) {
        const Index x = h[hexcell::kEdges[e][0]], y = h[hexcell::kEdges[e][1]];
        if ((x == a && y == b) || (x == b && y == a)) return e;
    }
    return -1;
}

// The smallest hex that has an edge from a to b (a hex holding both as a face
// diagonal does not count), given `holder`, one that has it: the first hex of
// both sorted rows, in order, that has the edge, so the merge stops there, at
// `holder` at the latest.
Index smallestHolder(const Csr& nodeHexes, const std::vector<Hex>& hexes, Index a, Index b, Index holder) {
    const Index *p = nodeHexes.begin(a), *pe = nodeHexes.end(a), *q = nodeHexes.begin(b), *qe = nodeHexes.end(b);
    while (p != pe && q != qe) {
        if (*p < *q) ++p;
        else if (*q < *p) ++q;
        else {
            if (*p == holder || localEdgeWith(hexes[*p], a, b) >= 0) return *p;
            ++p;
            ++q;
        }
    }
    return kNone;
}

std::uint16_t ownedEdgeBits(const Csr& nodeHexes, const std::vector<Hex>& hexes, std::size_t h) {
    std::uint16_t bits = 0;
    for (int e = 0; e < 12; ++e) {
        const Index a = hexes[h][hexcell::kEdges[e][0]], b = hexes[h][hexcell::kEdges[e][1]];
        if (smallestHolder(nodeHexes, hexes, a, b, static_cast<Index>(h)) == static_cast<Index>(h) &&
            localEdgeWith(hexes[h], a, b) == e)
            bits |= static_cast<std::uint16_t>(1u << e);
    }
    return bits;
}

bool hasRepeatedNode(const Hex& hex) {
    for (int a = 0; a < 8; ++a)
        for (int b = a + 1; b < 8; ++b)
            if (hex[a] == hex[b]) return true;
    return false;
}

// The candidates hold both ends of one of the face's diagonals; each is
// checked against the full face.
int otherHolders(const Csr& nodeHexes, const std::vector<Hex>& hexes, std::size_t h, int f,
                 std::array<Index, kMaxHolders>& holders, std::array<std::int8_t, kMaxHolders>& faces) {
    const auto& lf = hexcell::kFaces[f];
    const int n = intersectRows(nodeHexes, hexes[h][lf[0]], hexes[h][lf[2]], holders);
    int kept = 0;
    for (int c = 0; c < n; ++c) {
        if (holders[c] == static_cast<Index>(h)) continue;
        const int g = matchingFace(hexes[holders[c]], hexes[h], f);
        if (g < 0) continue;
        holders[kept] = holders[c];
        faces[kept++] = static_cast<std::int8_t>(g);
    }
    return kept;
}

void linkFace(const Csr& nodeHexes, const std::vector<Hex>& hexes, std::size_t h, int f, bool repeats, FaceLink& L) {
    std::array<Index, kMaxHolders> holders;
    std::array<std::int8_t, kMaxHolders> faces;
    const int n = otherHolders(nodeHexes, hexes, h, f, holders, faces);
    L.other[f] = n > 0 ? holders[0] : kNone;
    L.otherFace[f] = n > 0 ? faces[0] : std::int8_t(-1);
    unsigned count = 1 + static_cast<unsigned>(n);  // this hex and the others
    if (repeats) count += static_cast<unsigned>(selfHolds(hexes[h], f));
    L.holders[f] = static_cast<std::uint8_t>(std::min(count, 255u));
}

int selfHolds(const Hex& hex, int f) {
    int n = 0;
    for (int g = 0; g < 6; ++g) n += g != f && sortedFace(hex, g) == sortedFace(hex, f);
    return n;
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

Csr nodeHexRows(const std::vector<Hex>& hexes, std::size_t N) {
    using Range = tbb::blocked_range<std::size_t>;
    Csr c = parallel::bucketItems(N, hexes.size() * 8, [&](std::size_t i) { return hexes[i / 8][i % 8]; });
    tbb::parallel_for(Range(0, c.items.size(), 8192), [&](const Range& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) c.items[i] /= 8;
    });
    return c;
}

std::optional<Quad> surfaceQuad(const HexMesh& mesh, std::size_t h, int f, int holders, Index other,
                                std::int8_t otherFace) {
    const bool boundary = holders == 1;
    const bool interface = holders == 2 && other != kNone && other > static_cast<Index>(h) &&
                           mesh.material[h] != mesh.material[other];
    if (!boundary && !interface) return std::nullopt;
    Quad quad;
    for (int i = 0; i < 4; ++i) quad.nodes[i] = mesh.hexes[h][hexcell::kFaces[f][i]];
    quad.hex = {static_cast<Index>(h), other};
    quad.localFace = {static_cast<std::int8_t>(f), otherFace};
    return quad;
}

void setSurfaceQuads(Topology& t, const HexMesh& mesh, std::vector<Quad> quads) {
    t.quads = std::move(quads);
    t.nodeOnBoundary.assign(mesh.nodes.size(), 0);
    for (std::size_t q = 0; q < t.quads.size(); ++q) {
        if (t.quads[q].boundary()) {
            t.boundaryQuads.push_back(static_cast<Index>(q));
            for (Index v : t.quads[q].nodes) t.nodeOnBoundary[v] = 1;
        } else {
            t.interfaceQuads.push_back(static_cast<Index>(q));
        }
    }
    for (std::size_t v = 0; v < mesh.nodes.size(); ++v)
        if (t.nodeOnBoundary[v]) t.boundaryNodes.push_back(static_cast<Index>(v));
}

}  // namespace isohex::detail

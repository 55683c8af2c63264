#include "FaceLinks.hpp"

#include <algorithm>

#include "isohex/core/HexCell.hpp"

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
    // a hex listing the same node set on two of its faces holds it twice
    if (repeats)
        for (int g = 0; g < 6; ++g)
            if (g != f && sortedFace(hexes[h], g) == sortedFace(hexes[h], f)) ++count;
    L.holders[f] = static_cast<std::uint8_t>(std::min(count, 255u));
}

}  // namespace isohex::detail

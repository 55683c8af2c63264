#pragma once
// Which hexes hold a face or an edge, from the node-to-hex rows alone: the
// primitives buildTopology numbers quads and edges with, shared with
// validate(), which checks a mesh without building the quads.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "isohex/core/Csr.hpp"
#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"

namespace isohex::detail {

constexpr std::size_t kMaxHolders = 64;

// Hexes in both sorted rows (a hex listed twice in a row counts once).
template <std::size_t Cap>
inline int intersectRows(const Csr& c, Index a, Index b, std::array<Index, Cap>& out) {
    const Index *p = c.begin(a), *pe = c.end(a), *q = c.begin(b), *qe = c.end(b);
    int n = 0;
    while (p != pe && q != qe) {
        if (*p < *q) ++p;
        else if (*q < *p) ++q;
        else {
            if ((n == 0 || out[n - 1] != *p) && n < static_cast<int>(Cap)) out[n++] = *p;
            ++p;
            ++q;
        }
    }
    return n;
}


bool hasRepeatedNode(const Hex& hex);

// The nodes of face f of h, sorted.
std::array<Index, 4> sortedFace(const Hex& h, int f);

// Local face of hex h made of exactly the nodes of face f of hex g, or -1.
int matchingFace(const Hex& h, const Hex& g, int f);

// The first local edge of h joining a and b, or -1.
int localEdgeWith(const Hex& h, Index a, Index b);

// The smallest hex that has an edge from a to b, given `holder`, one that has it.
Index smallestHolder(const Csr& nodeHexes, const std::vector<Hex>& hexes, Index a, Index b, Index holder);

// The local edges hex h owns, as bits: those whose smallest holder is h, at
// their first local edge there. Edge ids are numbered in owner order, then
// local edge order, so an owned edge's id is its owner's first id plus the
// owned bits below it.
std::uint16_t ownedEdgeBits(const Csr& nodeHexes, const std::vector<Hex>& hexes, std::size_t h);

// The other hexes holding face f of hex h, ascending, in holders[0..n), with
// the local face each holds it as; returns n.
int otherHolders(const Csr& nodeHexes, const std::vector<Hex>& hexes, std::size_t h, int f,
                 std::array<Index, kMaxHolders>& holders, std::array<std::int8_t, kMaxHolders>& faces);

// Per hex face: how many hexes hold it, and the smallest other holder with
// its local face (the owner when it is smaller than this hex).
struct FaceLink {
    std::array<Index, 6> other;
    std::array<std::int8_t, 6> otherFace;
    std::array<std::uint8_t, 6> holders;
    bool owned(std::size_t h, int f) const { return other[f] == kNone || other[f] > static_cast<Index>(h); }
};

// Throws an Error if the materials do not match the hexes, the mesh is too
// large for 32-bit ids, or a hex names a node that does not exist.
void checkIndices(const HexMesh& mesh);

// node -> hexes holding it, rows sorted (a hex holding a node twice is listed twice).
Csr nodeHexRows(const std::vector<Hex>& hexes, std::size_t N);

// How many other faces of `hex` have the node set of its face f (a collapsed
// hex holds such a face more than once).
int selfHolds(const Hex& hex, int f);

// Links face f of hex h (whose nodes repeat if `repeats`) into L.
void linkFace(const Csr& nodeHexes, const std::vector<Hex>& hexes, std::size_t h, int f, bool repeats, FaceLink& L);

// Face f of hex h as a quad of a surface, if it is one: on the boundary (h its
// only holder) or on an interface (two holders of different material, h the
// smaller). `other` is the smallest other holder (kNone if none) with its face.
std::optional<Quad> surfaceQuad(const HexMesh& mesh, std::size_t h, int f, int holders, Index other,
                                std::int8_t otherFace);

// Sets t.quads to `quads` (surface quads in owner order) with boundaryQuads,
// interfaceQuads, nodeOnBoundary and boundaryNodes.
void setSurfaceQuads(Topology& t, const HexMesh& mesh, std::vector<Quad> quads);

}  // namespace isohex::detail

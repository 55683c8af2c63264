#pragma once
// Pillowing: inserting one sheet of hexes around a set of hexes (the shrink
// set), so that no hex has two faces on its boundary.
#include <cstddef>
#include <vector>

#include "isohex/core/HexMesh.hpp"

namespace isohex {

struct PillowOptions {
    // The inner copy of a split node starts this fraction of the local edge
    // length inside the shrink set, along the averaged surface normal, turned
    // where needed so that it points inside every boundary quad's corner at
    // the node (else the sheet hex on that quad starts inverted whatever the
    // length). The fraction is halved per node (up to `maxHalvings` times)
    // where the start position would invert an adjacent hex.
    double inset = 0.3;
    // Off: the averaged normal as it is (the start before the optimiser had
    // a valid one: for comparisons and tests of untangling).
    bool turnIntoCorners = true;
    int maxHalvings = 6;
    // Then each copy the halvings shortened goes on alone, sequentially,
    // towards 70% of its full step as far as the valid hexes around it stay
    // valid (the halvings shorten every copy of an inverted hex together).
    // Off: the halvings alone, for comparisons.
    bool stepOnAlone = true;
    // Find the shrink set's boundary faces through the node -> hex adjacency
    // of the whole shrink set instead of first narrowing it to the nodes the
    // face-parity test puts on the boundary (pillow falls back to this by
    // itself if the narrowed result is not a closed manifold). Same result,
    // slower; for tests.
    bool exactBoundary = false;
};

struct PillowResult {
    Index firstNewHex = 0;             // the new sheet's hexes are [firstNewHex, mesh.hexCount())
    Index firstNewNode = 0;            // inner copies are [firstNewNode, mesh.nodeCount())
    std::vector<Index> copyOf;         // per inner copy, the original node it was split from
    std::size_t invertedAtStart = 0;   // hexes still inverted after placing the copies
};

// Inserts one sheet of hexes between the hexes in `shrinkSet` and everything
// else (other hexes or the outside): every node on the shrink set's boundary
// is split, hexes of the shrink set take the copy, and one new hex (material of
// the shrink-set hex) is made per boundary quad. Nodes of the rest of the mesh
// keep their index, position and class, so a surface mesh on the boundary is
// unchanged; copies are interior nodes. Throws isohex::Error, leaving the mesh
// untouched, if the shrink set is empty or its boundary is not a closed
// 2-manifold (an edge in more than two of its quads, or a node where two parts
// touch). The result is the same for any thread count.
PillowResult pillow(HexMesh& mesh, const std::vector<Index>& shrinkSet, const PillowOptions& opt = {});

// Pillows every material region on its own (shrink set = all hexes of that
// material, in increasing material order), so each outer surface gets one
// sheet and each interface two (one per side); with layers > 1 each new sheet
// is diced into `layers` sheets. Returns the results in order.
std::vector<PillowResult> pillowAllMaterials(HexMesh& mesh, int layers = 1, const PillowOptions& opt = {});

}  // namespace isohex

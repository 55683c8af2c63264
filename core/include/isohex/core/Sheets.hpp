#pragma once
// Sheet operations (seed chapter 3.3): pillowing a shrink set, dicing a sheet,
// extracting a sheet, and choosing sheets for the seed's control experiments.
#include <cstdint>
#include <vector>

#include "isohex/core/Dual.hpp"
#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"

namespace isohex {

struct PillowOptions {
    // The inner copy of a split node starts this fraction of the local edge
    // length inside the shrink set, along the averaged surface normal. The
    // fraction is halved per node (up to `maxHalvings` times) where the start
    // position would invert an adjacent hex.
    double inset = 0.3;
    int maxHalvings = 6;
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
// touch).
PillowResult pillow(HexMesh& mesh, const std::vector<Index>& shrinkSet, const PillowOptions& opt = {});

// Pillows every material region on its own (shrink set = all hexes of that
// material, in increasing material order), so each outer surface gets one
// sheet and each interface two (one per side). Returns the results in order.
std::vector<PillowResult> pillowAllMaterials(HexMesh& mesh, int layers = 1, const PillowOptions& opt = {});

// Copies a sheet `copies` times in parallel (seed 3.3.1.2): each of its
// edges is split into copies+1 equal parts and each of its hexes into
// copies+1 hexes. Returns the number of hexes added. Throws if the sheet
// crosses itself inside a hex.
std::size_t dice(HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet, int copies);

// Removes a sheet by collapsing its edges (seed 3.3.3.1). Refuses (throws
// isohex::Error saying why, mesh untouched) when that would merge nodes of two
// different surfaces or curves, pinch a surface (an edge between two nodes of
// one surface that runs through the solid), remove every hex of a material,
// or leave an invalid mesh. Returns the number of hexes removed.
std::size_t extract(HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet);

// --- choosing sheets
// The sheet through the edge joining nodes a and b (throws if no such edge).
Index sheetThroughEdge(const HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index a, Index b);
// Sheets that have an edge with a node on a boundary or interface surface.
std::vector<Index> sheetsTouchingSurfaces(const Topology& topo, const DualSheets& sheets);
// Sheets whose edges each join a surface node to an interior node and whose
// hexes each have a face on a surface: the fundamental sheets pillowing made.
std::vector<Index> fundamentalSheets(const HexMesh& mesh, const Topology& topo, const DualSheets& sheets);
// `count` distinct sheets drawn with a seeded generator from the sheets not in
// `exclude` (deterministic for a given mesh and seed).
std::vector<Index> randomSheets(const DualSheets& sheets, std::size_t count, std::uint64_t seed,
                                const std::vector<Index>& exclude = {});

}  // namespace isohex

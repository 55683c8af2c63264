#pragma once
// Choosing dual sheets to dice or collapse: by an edge, by where they lie,
// or at random (for the seed's control experiments).
#include <cstdint>
#include <vector>

#include "isohex/core/Dual.hpp"
#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"

namespace isohex {

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

#pragma once
// Private to insertion/src: steps 1-3 of the insertion (SheetInsertion.hpp),
// which side of the surface every hex goes to.
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/insertion/SheetInsertion.hpp"
#include "isohex/insertion/TriangleTree.hpp"

namespace isohex::insertion::detail {

// The side of a hex: an index into per-side arrays.
inline constexpr std::int8_t kInside = 0;   // Side1
inline constexpr std::int8_t kOutside = 1;  // Side2
inline constexpr std::int8_t kNoSide = -1;

// Per hex, the side of `surface` it goes to, such that the boundary of each
// side is a closed 2-manifold. Fills the intersected, flood, repair and side
// counts of `result`. Throws isohex::Error if the surface crosses no hex
// edge, the repair does not finish in options.maxRepairRounds rounds, or a
// side is empty. `surface.inside` is called from this thread only.
std::vector<std::int8_t> assignSides(const HexMesh& mesh, const Topology& topo, const TriangleTree& surface,
                                     const InsertOptions& options, InsertResult& result);

}  // namespace isohex::insertion::detail

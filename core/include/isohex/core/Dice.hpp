#pragma once
// Dicing a dual sheet: copying one layer of hexes in parallel.
#include <cstddef>

#include "isohex/core/Dual.hpp"
#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"

namespace isohex {

// Copies a sheet `copies` times in parallel (seed 3.3.1.2): each of its
// edges is split into copies+1 equal parts and each of its hexes into
// copies+1 hexes. Returns the number of hexes added. Throws if the sheet
// crosses itself inside a hex. `topo` and `sheets` are those of `mesh` and are
// out of date afterwards.
std::size_t dice(HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet, int copies);

}  // namespace isohex

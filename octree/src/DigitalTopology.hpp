#pragma once
// The digital topology of one grid point (private to octree/): whether
// changing its label keeps the components, tunnels and cavities of a set
// (topological numbers), and how it changes a region's Euler characteristic.
// The non-manifold repair and the grid edits decide their flips with them.
#include <array>
#include <cstdint>

#include "isohex/octree/Labels.hpp"

namespace isohex::octree {

// Change of the Euler characteristic of material m's solid (the union of the
// closed cubes around its points) when point (i, j, k) joins it (`add`) or
// leaves it: the point's cube meets the cubes of its m-neighbours in a complex
// K of its faces, edges and vertices, and chi changes by +-(1 - chi(K)). The
// boundary surface's chi is twice the solid's, so 0 means the flip keeps the
// Euler characteristic that regionTopology reports.
int eulerChange(const Labels& l, int i, int j, int k, std::int32_t m, bool add);

// Topological number of the set `in` (3x3x3 neighbourhood, x fastest, the
// centre ignored) for 6- or 26-adjacency (Bertrand and Malandain 1994): with
// 6, the 6-components of the set within the 18-neighbourhood that hold a
// 6-neighbour of the centre; with 26, the 26-components in the 26-neighbourhood.
// A point is simple for a set (adding or removing it keeps the set's
// components, tunnels and cavities) when the set's number for 26 and its
// complement's for 6 are both 1.
int topoNumber(const std::array<bool, 27>& in, int adjacency);

}  // namespace isohex::octree

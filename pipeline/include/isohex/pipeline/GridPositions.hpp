#pragma once
// Hex centres in a grid's own coordinates, for the grid edits the retries and
// the feature removal make next to hexes (octree::editNearInvertedHexes takes
// fractional grid coordinates).
#include <array>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/octree/Grid.hpp"

namespace isohex::pipeline {

// The centres of `hexes` of `mesh` as (i, j, k) with centre = grid.point(i, j, k).
std::vector<std::array<double, 3>> hexCentresInGrid(const HexMesh& mesh, const octree::Grid& grid,
                                                    const std::vector<Index>& hexes);

}  // namespace isohex::pipeline

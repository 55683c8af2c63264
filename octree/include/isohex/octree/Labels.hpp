#pragma once
// A material label per grid point, and sampling them from a Domain.
#include <cstdint>
#include <vector>

#include "isohex/octree/Domain.hpp"
#include "isohex/octree/Grid.hpp"

namespace isohex::octree {

// Material label per grid point (x fastest), 0 = background.
struct Labels {
    Grid grid;
    std::vector<std::int32_t> material;

    // The label of point (i, j, k); 0 (background) off the grid.
    std::int32_t at(int i, int j, int k) const { return grid.contains(i, j, k) ? material[grid.index(i, j, k)] : 0; }
};

// Samples materialAt at every grid point (parallel). Points on the grid's
// outer layer are forced to background so every region is closed, unless
// `keepBorder` (used when the exterior itself is meshed out to the box).
Labels sampleLabels(const Domain& domain, const Grid& grid, bool keepBorder = false);

}  // namespace isohex::octree

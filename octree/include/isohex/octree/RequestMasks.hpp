#pragma once
// Refinement requests for the 27-tree (RefinementTree.hpp): one byte per cell
// and level, index l = level 1 .. top, each mask sized like that level's
// RefinementLevel::dims. Criteria make their own masks; the adaptive mesher
// ORs them before closeRefinement, so a cell any criterion asks for is
// refined and each criterion's count stays its own.
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/octree/Grid.hpp"

namespace isohex::octree {

using RequestMasks = std::vector<std::vector<std::uint8_t>>;

// Cells per axis at `level` (>= 0) of a tree over `points` grid points per
// axis, as closeRefinement sizes them.
std::array<int, 3> levelDims(const std::array<int, 3>& points, int level);

// Masks for levels 1 .. top with no cell requested.
RequestMasks emptyRequests(const std::array<int, 3>& points, int top);

// into[l] |= from[l] for every level; an empty mask is all zeros, and `into`
// grows to hold from's levels. Masks of one level in two sizes are an
// internal error.
void orRequests(RequestMasks& into, const RequestMasks& from);

// Requested cells over every level.
std::size_t countRequests(const RequestMasks& masks);

// Sets every cell within `rings` cells (faces, edges and corners: the cube
// of side 2 rings + 1) of a set one; separable, one pass per axis.
void dilateCells(std::vector<std::uint8_t>& mask, const std::array<int, 3>& dims, int rings);

// The level-1 request mask of the cells holding the grid points nearest the
// world positions `at` (grid.dims points per axis; positions off the grid
// are skipped), dilated by `rings` cells: the hook that refines around hexes
// the optimiser leaves poor (issue 38), before the tree is closed again.
std::vector<std::uint8_t> requestsAround(const std::vector<Vec3>& at, const Grid& grid, int rings);

}  // namespace isohex::octree

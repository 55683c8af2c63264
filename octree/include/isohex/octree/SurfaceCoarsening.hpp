#pragma once
// Which cells of the 27-tree may stay unrefined where the surface crosses
// them: the refinement criterion of the adaptive mesher that lets a leaf of
// any level straddle a boundary or an interface.
//
// A level-l cell (3^l grid points per axis) is looked at over its points and
// one point around them (the points whose hexes touch it). It may stay
// coarse when that block holds one label, or two labels whose parts are each
// one 6-connected component with Euler characteristic 1 (no tunnel, handle
// or cavity), meeting the block's border in one 6-connected patch each (so
// the surface between them is one disk crossing the block: no speck, thin
// plate, rod or fold hides inside the cell). Three or more labels (a triple
// line, or a material meeting another and the outside) keep the cell
// refined, down to the uniform hexes there. A cell with a refined child is
// refined by the closure anyway and is not looked at.
//
// The result has the shape of closeRefinement's requests (one flag per cell
// per level), so other criteria (user sizing) are OR-ed into it.
#include <array>
#include <cstdint>
#include <vector>

#include "isohex/octree/Labels.hpp"

namespace isohex::octree {

// Per level l (index l = 1 .. top; index 0 empty): one flag per level-l cell.
using LevelRequests = std::vector<std::vector<std::uint8_t>>;

// The highest level (<= maxLevel, >= 1) whose cells are not wider than the
// grid: the top of the tree the adaptive mesher builds over `points`.
int treeTop(const std::array<int, 3>& points, int maxLevel);

// Cells per axis of level l over `points` grid points per axis.
std::array<int, 3> levelCells(const std::array<int, 3>& points, int level);

// The surface criterion: flags the cells of levels 1 .. top that must be refined.
LevelRequests surfaceRequests(const Labels& labels, int top);

// Sets every flag of `from` in `into` (levels and sizes must agree where both
// have a level; `into` grows to hold `from`'s levels).
void orRequests(LevelRequests& into, const LevelRequests& from);

}  // namespace isohex::octree

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
#include "isohex/octree/RequestMasks.hpp"

namespace isohex::octree {

// The surface criterion: flags the cells of levels 1 .. top that must be refined.
RequestMasks surfaceRequests(const Labels& labels, int top);

}  // namespace isohex::octree

#pragma once
// The adaptive 27-tree over the hex lattice (3-refinement): which cells are
// refined and which carry a transition template, level by level.
//
// Level 0 is the finest grid (one hex per grid point, the uniform mesher's
// hexes); a level-l cell is the cube of 3^l x 3^l x 3^l level-0 hexes of the
// grid points [3^l m, 3^l (m + 1)) per axis, so its corners are level-0 nodes
// and cells nest exactly. The roots are the cells of the top level.
//
// Structure: one dense array per level of one byte per cell (refined flag)
// and one byte per cell (marked-corner mask), like an image pyramid. The
// grid itself is dense (4 bytes of label per point), and level l has 27^-l
// as many cells as points, so the whole tree costs 2/26 byte per grid point
// (under 2% of the labels), with neighbours found by index arithmetic: no
// hashing, no pointers, and the same bytes for any thread count. A linear
// (Morton-keyed) octree would save memory only where the labels themselves
// are sparse, which they are not.
//
// Closure (marked-node scheme): a refined cell marks its 8 corners; an
// unrefined cell takes the template of its marked corners
// (TransitionTemplates.hpp), or marks the corners its promotion adds (the
// fewest that reach a mask with a template), until a fixed point. Levels are closed bottom-up: the parent of every level-l cell
// that is refined or carries a template is refined at level l + 1, because
// template hexes are final and deeper refinement must sit inside fully
// refined parents. So a leaf's level differs from that of any face, edge or
// corner neighbour by at most one.
//
// Templates (TransitionTemplates.hpp): vertex, edge, face, two-face (the
// six corners of two adjacent faces: the convex edge of a coarse region that
// refined cells wrap) and the 27 unit cubes for masks that mark an end of
// every edge (a convex corner of such a region has seven). Without the
// two-face template a coarse region enclosed by refined cells was eaten from
// its edges and the closure refined the whole inside; an exhaustive search
// over every marking of a block whose outer shell is refined
// (tools/template-closure-search.py) shows that no closure rule avoids it
// without that template, and that one exists with it. Other masks (e.g. two
// opposite corners, or a face and one more corner) are promoted to the
// superset with a template and the fewest added corners.
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "isohex/octree/Labels.hpp"

namespace isohex::octree {

struct RefinementLevel {
    std::array<int, 3> dims{0, 0, 0};  // cells per axis
    std::vector<std::uint8_t> refined;  // per cell: 1 when split into 27 children
    std::vector<std::uint8_t> marks;    // per unrefined cell: its marked corners (bit x + 2y + 4z)

    std::size_t index(int i, int j, int k) const {
        return (static_cast<std::size_t>(k) * static_cast<std::size_t>(dims[1]) + static_cast<std::size_t>(j)) *
                   static_cast<std::size_t>(dims[0]) +
               static_cast<std::size_t>(i);
    }
    bool contains(int i, int j, int k) const {
        return i >= 0 && j >= 0 && k >= 0 && i < dims[0] && j < dims[1] && k < dims[2];
    }
};

struct RefinementTree {
    std::array<int, 3> points{0, 0, 0};  // level-0 cells (grid points) per axis
    // levels[l] for l = 1 .. top; levels[0] is empty (level-0 cells are single hexes)
    std::vector<RefinementLevel> levels;

    int top() const { return static_cast<int>(levels.size()) - 1; }
    // Cells refined by the closure that no request asked for, per level.
    std::vector<std::size_t> promoted;
    // Cells a request (a refinement criterion) asked to refine, per level.
    std::vector<std::size_t> requested;
    // Cells refined at each level by the grading's dilation (Grading.hpp) that
    // neither a request nor the closure refined.
    std::vector<std::size_t> graded;
};

// The closed tree over `points` grid points per axis with `top` levels
// (3^top points per root side, top >= 1). requests[l] (l = 1 .. top, may be
// empty) flags the level-l cells that must be refined. `grading` > 0 keeps
// that many cells of every level around its refined and templated cells
// before the next coarser level (refineGradedParents, Grading.hpp); 0 is the
// closure's own one-level balance.
RefinementTree closeRefinement(const std::array<int, 3>& points, int top,
                               const std::vector<std::vector<std::uint8_t>>& requests, int grading = 0);

// The refinement criteria of the adaptive mesher.
struct RefinementSettings {
    // Levels above the finest: coarse cells are up to 3^maxLevel grid steps wide.
    int maxLevel = 3;
};

// The top level of a tree over `points` grid points per axis: at most
// maxLevel (and at least 1), and no higher than the level whose cells are
// not wider than the grid.
int topLevelFor(const std::array<int, 3>& points, int maxLevel);

// Criterion (a) as a request: the level-1 mask (index 1 of the result; index
// 0 empty) of the cells refineAtLabelChanges refines.
std::vector<std::vector<std::uint8_t>> labelChangeRequests(const Labels& labels);

// Criterion (a): a level-1 cell is refined (down to the finest hexes) unless
// every grid point in it and one point around it has one label, so every
// boundary and interface quad, and every node of a cell the surface crosses,
// stays at the finest level, where dual contouring places it. Where labels are
// uniform the closure coarsens. The top level is clamped so a root is not
// wider than the grid.
RefinementTree refineAtLabelChanges(const Labels& labels, const RefinementSettings& settings);

}  // namespace isohex::octree

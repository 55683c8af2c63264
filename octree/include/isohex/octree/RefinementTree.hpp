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
// (TransitionTemplates.hpp), or is refined when no template fits, until a
// fixed point. Levels are closed bottom-up: the parent of every level-l cell
// that is refined or carries a template is refined at level l + 1, because
// template hexes are final and deeper refinement must sit inside fully
// refined parents. So a leaf's level differs from that of any face, edge or
// corner neighbour by at most one.
//
// Known limit of this template set (vertex, edge, face, and the 27 unit
// cubes for masks that mark an end of every edge): a cell whose two
// adjacent faces are marked (six corners: the convex edge of a coarse region
// wrapped by refined cells) has no template, and its promotion adds a corner
// that its neighbours further inside must take, so a coarse region enclosed
// by refined cells is eaten from its edges: the closure then refines the
// whole inside. No other choice of marks avoids this: an exhaustive search
// over every marking of a block whose outer shell is refined
// (tools/template-closure-search.py) finds none that keeps the centre cell
// plain with this template set, and finds one as soon as the two-face masks
// are allowed; so the two-face template is required, not a closure rule.
// What it must show: the two marked faces and the two end faces split in
// nine, the two other faces the EDGE pattern whose 3-to-1 strips meet at
// the unsplit edge. Its x-chords X1 and X3 are one sheet that turns at that
// edge, and that sheet meets the middle sheet X2 in a curve whose ends are
// the two strips' top quads, which share an edge, so the curve must cross
// other sheets. With only the eight sheets the faces ask for, the crossings
// checked (the turn dipping past the planes next to the edge) put two strip
// quads of one face on one hex (a flat hex); an extra closed (pillow) sheet
// is the likely way out. Nor is it a sweep of the 2-D strip across the
// cross-section (columns split in three, whole, or strip pieces): that needs
// at least five cells around the unsplit edge where the end faces have one
// (tools/two-face-sweep-template.py builds and checks such a sweep: its end
// faces show 14 quads, so every face with three marked corners would have
// to, and the seven-corner template would then need an odd count there).
// It cannot keep unit cubes beside its corner column either (the corner hex
// would need the two strips' corner quads, which share no edge, as adjacent
// faces). Deriving it is the next step (Ito, Shih and Soni 2009; Tong and
// Zhang 2025 for relaxed balance). Until then the adaptive mesh of a closed
// object keeps the hex count of the uniform one.
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
};

// The closed tree over `points` grid points per axis with `top` levels
// (3^top points per root side, top >= 1). requests[l] (l = 1 .. top, may be
// empty) flags the level-l cells that must be refined.
RefinementTree closeRefinement(const std::array<int, 3>& points, int top,
                               const std::vector<std::vector<std::uint8_t>>& requests);

// The refinement criteria of the adaptive mesher.
struct RefinementSettings {
    // Levels above the finest: coarse cells are up to 3^maxLevel grid steps wide.
    int maxLevel = 3;
};

// Criterion (a): a level-1 cell is refined (down to the finest hexes) unless
// every grid point in it and one point around it has one label, so every
// boundary and interface quad, and every node of a cell the surface crosses,
// stays at the finest level, where dual contouring places it. Where labels are
// uniform the closure coarsens. The top level is clamped so a root is not
// wider than the grid.
RefinementTree refineAtLabelChanges(const Labels& labels, const RefinementSettings& settings);

}  // namespace isohex::octree

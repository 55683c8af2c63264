#pragma once
// Edits of the labels that change the solid on purpose, a few grid points at
// a time: dropping specks, filling one-cell pits, and moving points where
// the mesh keeps inverted hexes.
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "isohex/octree/Labels.hpp"

namespace isohex::octree {

// Keeps, for every material, only its largest 6-connected region of grid
// points (the others become background): drops the specks of noise that an
// intensity threshold leaves around an organ. Returns the points removed.
std::size_t keepLargestComponents(Labels& labels);

// Fills one-grid-cell pits of the background: a background point with exactly
// five face neighbours of one material (the sixth is background) joins that
// material, and again for the points this uncovers, until none is left, so a
// well one cell wide is filled to its rim. Such a pit's floor is a boundary
// quad whose four corners each have three boundary quads; the fundamental
// sheet then needs a convex hex over a nearly flat floor with four 90-degree
// corners, which no node placement gives.
// The filled points are simple (dead ends of the background, 26-joined to
// the material), so no region gains or loses a component, tunnel or cavity;
// two pits facing each other (a two-point cavity) are left alone. Points on
// the grid's outer layer are never filled. Returns the points filled.
std::size_t fillOneCellPits(Labels& labels);

// One grid point given another material.
struct PointEdit {
    std::size_t point = 0;
    std::int32_t from = 0, to = 0;
};

// The grid edit behind the pipeline's retry for hexes the optimiser leaves
// inverted. Such hexes sit where the grid's shape asks the sheet for a convex
// hex no node placement gives: a bump one point wide at a junction of
// materials, a pit, a notch. Near each position (fractional grid coordinates
// of an inverted hex's centre), among the 27 points around it that are not
// `frozen` and not on the grid's outer layer, the most exposed one (fewest
// face neighbours of its own material, at most `maxSame`) takes the material
// most of its face neighbours hold, provided the change is simple for both
// materials (every material keeps its components, tunnels and cavities; a
// point joining or leaving the background is also simple for the union of
// all materials, so the exterior and the pockets of background between
// materials keep theirs) and leaves the 8 blocks around the point manifold.
// Positions off the grid (or not finite) are skipped. At most one edit per place:
// a position with an edit of this call among its 27 points is skipped.
// Returns the edits, in the order made.
std::vector<PointEdit> editNearInvertedHexes(Labels& labels, const std::vector<std::array<double, 3>>& positions,
                                             const std::vector<std::size_t>& frozen = {}, int maxSame = 2);

}  // namespace isohex::octree

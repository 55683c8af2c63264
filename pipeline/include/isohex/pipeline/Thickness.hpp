#pragma once
// The thickness criterion of the adaptive mesher: a cell is refined where a
// material in it is thinner than two cells, so thin plates, rods and shells
// keep cells small enough to hold them.
//
// Local thickness at a grid point (Hildebrand and Ruegsegger) is the
// diameter of the largest ball inside its material that holds the point; it
// is below 2r exactly where the point is not in the material's opening by a
// ball of radius r. The opening is computed with two distance maps, both by
// OpenVDB's fast sweeping (tools::fogToSdf): the distance d to the nearest
// grid point on a label boundary (a point with a face neighbour of another
// label), which gives the erosion {d + 1/2 >= r} (the surface lies half a
// step beyond the boundary points), and per level the distance to that
// erosion, whose points within r are the opening. Distances are in grid
// steps, so a level-l cell is 3^l steps wide on every axis (anisotropic
// grids measure thickness in cells, as the cells are); fast sweeping is
// first order, good to about half a step, far below the 3-step width of the
// finest cells it decides.
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/RequestMasks.hpp"

namespace isohex::pipeline {

// The masks (levels 1 .. top) of the level-l cells holding a material grid
// point whose local thickness is below two level-l cell widths.
octree::RequestMasks thicknessRequests(const octree::Labels& labels, int top);

}  // namespace isohex::pipeline

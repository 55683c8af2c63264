#pragma once
// The grading of the 27-tree (--grading G): at least G cells of a level
// around its finer region before the next coarser level begins.
//
// closeRefinement refines the parent of every level-(l-1) cell that is
// refined or carries a transition template, so a leaf's level differs from
// its neighbours' by at most one but a coarser level may start right behind
// the transition cells (grading 0, the default). With G > 0 the set of
// level-(l-1) cells that are refined or carry a template is first dilated by
// G cells (faces, edges and corners), and the parents of the dilated set are
// refined: the level-(l-1) leaves then reach at least G cells beyond the
// transition cells, rounded up to whole parents, before level-l leaves.
#include <cstddef>

#include "isohex/octree/RefinementTree.hpp"

namespace isohex::octree {

// Refines the parent of every `child` cell within `rings` cells of a refined
// or templated child (after the closure of the child level). Returns the
// parents this refined that were not refined before.
std::size_t refineGradedParents(const RefinementLevel& child, RefinementLevel& parent, int rings);

}  // namespace isohex::octree

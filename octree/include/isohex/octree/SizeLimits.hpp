#pragma once
// User sizing of the 27-tree: the largest cell width allowed around each
// level-1 cell (world units), and the requests that enforce it.
//
// A limit is kept per level-1 cell (3 x 3 x 3 grid points; 4/27 byte per
// grid point); a coarser cell's limit is the minimum over the level-1 cells
// it holds (a pyramid, like the tree's own arrays). A level-l cell is
// requested refined while it is wider than its limit: 3^l times the finest
// hex width (the widest grid step) above the limit. The finest hexes stay
// whatever the limit: --size (or the chosen level) is the smallest size.
#include <array>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "isohex/octree/Labels.hpp"
#include "isohex/octree/RequestMasks.hpp"

namespace isohex::octree {

struct CellSizeLimits {
    std::array<int, 3> dims{0, 0, 0};  // level-1 cells per axis
    std::vector<float> limit;          // per level-1 cell: widest cell allowed; +infinity: none

    std::size_t index(int i, int j, int k) const {
        return (static_cast<std::size_t>(k) * static_cast<std::size_t>(dims[1]) + static_cast<std::size_t>(j)) *
                   static_cast<std::size_t>(dims[0]) +
               static_cast<std::size_t>(i);
    }
};

// No limit anywhere, over `points` grid points per axis.
CellSizeLimits noSizeLimits(const std::array<int, 3>& points);

// Per-label sizes (--label-size L=S): a level-1 cell holding a grid point of
// label L is limited to S (the smallest S of its labels); labels without a
// size impose nothing.
CellSizeLimits labelSizeLimits(const Labels& labels, const std::vector<std::pair<std::int32_t, double>>& sizes);

// The masks (levels 1 .. top) of the cells wider than their limit.
// `finestWidth`: the width of a level-0 hex (world units).
RequestMasks requestsForLimits(const CellSizeLimits& limits, const std::array<int, 3>& points, double finestWidth,
                               int top);

// The coarsest level (0 .. maxLevel) whose cells are no wider than maxSize
// (--max-size): 3^level * finestWidth <= maxSize.
int levelForMaxSize(double maxSize, double finestWidth, int maxLevel);

}  // namespace isohex::octree

#pragma once
// The user's sizing of the adaptive mesher and the thickness criterion, as
// requests for the 27-tree (octree/RequestMasks.hpp), ORed with the surface
// criteria's before the tree is closed:
//   --max-size S     the top level is the coarsest whose cells are no wider
//                    than S (below three finest hexes: every level-1 cell
//                    is refined, the uniform mesh);
//   --label-size L=S cells holding label L no wider than S;
//   --size-image F   cells no wider than the image's minimum over them
//                    (SizeImage.hpp);
//   thickness        cells where a material is thinner than two cells
//                    (Thickness.hpp; on unless --no-thickness-refinement).
// The finest hexes are the grid's (--size, its alias --min-size, or the
// chosen level): no criterion goes below them.
#include <cstddef>
#include <optional>

#include "isohex/octree/RequestMasks.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Prepare.hpp"

namespace isohex::pipeline {

// What the sizing asked for: cells requested by each criterion over every
// level (a cell several criteria ask for counts for each).
struct SizingFacts {
    std::optional<int> maxSizeLevel;  // the coarsest level --max-size allows
    std::size_t maxSize = 0, labelSize = 0, sizeImage = 0, thickness = 0;
};

// The width of a finest hex (world units): the widest grid step.
double finestWidth(const octree::Grid& grid);

// The top level of the tree: settings.adaptiveLevels, no higher than the
// grid allows (octree::topLevelFor) nor than --max-size allows (at least 1).
int sizingTopLevel(const Prepared& p, const MeshSettings& settings, SizingFacts& facts);

// The requests of every sizing criterion for a tree of `top` levels over
// p.labels, ORed; the count of each in `facts`.
octree::RequestMasks sizingRequests(const Prepared& p, const MeshSettings& settings, int top, SizingFacts& facts);

}  // namespace isohex::pipeline

#include "isohex/pipeline/Sizing.hpp"

#include <algorithm>

#include "isohex/octree/RefinementTree.hpp"
#include "isohex/octree/SizeLimits.hpp"
#include "isohex/pipeline/SizeImage.hpp"
#include "isohex/pipeline/Thickness.hpp"

namespace isohex::pipeline {

double finestWidth(const octree::Grid& grid) {
    const auto s = grid.spacing();
    return std::max({s[0], s[1], s[2]});
}

int sizingTopLevel(const Prepared& p, const MeshSettings& settings, SizingFacts& facts) {
    int most = settings.adaptiveLevels;
    if (settings.maxSize) {
        facts.maxSizeLevel = octree::levelForMaxSize(*settings.maxSize, finestWidth(p.labels.grid), most);
        most = std::max(1, *facts.maxSizeLevel);
    }
    return octree::topLevelFor(p.labels.grid.dims, most);
}

octree::RequestMasks sizingRequests(const Prepared& p, const MeshSettings& settings, int top, SizingFacts& facts) {
    const auto& points = p.labels.grid.dims;
    const double h = finestWidth(p.labels.grid);
    octree::RequestMasks all = octree::emptyRequests(points, top);
    auto add = [&](const octree::RequestMasks& m, std::size_t& count) {
        count = octree::countRequests(m);
        octree::orRequests(all, m);
    };
    if (facts.maxSizeLevel && *facts.maxSizeLevel == 0) {  // cells of three finest hexes are too wide already
        octree::RequestMasks every = octree::emptyRequests(points, top);
        std::fill(every[1].begin(), every[1].end(), std::uint8_t{1});
        add(every, facts.maxSize);
    }
    if (!settings.labelSizes.empty())
        add(octree::requestsForLimits(octree::labelSizeLimits(p.labels, settings.labelSizes), points, h, top),
            facts.labelSize);
    if (!settings.sizeImage.empty()) {
        const imaging::Volume sizes = loadSizeImage(settings.sizeImage, settings.load);
        add(octree::requestsForLimits(sizeImageLimits(sizes, p.labels.grid), points, h, top), facts.sizeImage);
    }
    if (settings.thicknessRefinement) add(thicknessRequests(p.labels, top), facts.thickness);
    return all;
}

}  // namespace isohex::pipeline

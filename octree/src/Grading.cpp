#include "isohex/octree/Grading.hpp"

#include "isohex/octree/RequestMasks.hpp"

namespace isohex::octree {

std::size_t refineGradedParents(const RefinementLevel& child, RefinementLevel& parent, int rings) {
    std::vector<std::uint8_t> busy(child.refined.size(), 0);
    for (std::size_t c = 0; c < busy.size(); ++c) busy[c] = child.refined[c] || child.marks[c];
    dilateCells(busy, child.dims, rings);
    std::size_t added = 0;
    for (int k = 0; k < child.dims[2]; ++k)
        for (int j = 0; j < child.dims[1]; ++j)
            for (int i = 0; i < child.dims[0]; ++i) {
                if (!busy[child.index(i, j, k)]) continue;
                std::uint8_t& p = parent.refined[parent.index(i / 3, j / 3, k / 3)];
                added += p == 0;
                p = 1;
            }
    return added;
}

}  // namespace isohex::octree

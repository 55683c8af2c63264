#include "isohex/octree/SizeLimits.hpp"

#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

namespace isohex::octree {

namespace {

// Whether a cell `width` wide is wider than `limit` (a relative slack so a
// limit equal to a level's width does not refine it).
bool wider(double width, float limit) { return width > static_cast<double>(limit) * (1 + 1e-6); }

// The limits of the next coarser level: the minimum over each 3 x 3 x 3 block.
CellSizeLimits coarser(const CellSizeLimits& fine) {
    CellSizeLimits c;
    for (int a = 0; a < 3; ++a) c.dims[a] = std::max(1, (fine.dims[a] + 2) / 3);
    c.limit.assign(static_cast<std::size_t>(c.dims[0]) * c.dims[1] * c.dims[2], std::numeric_limits<float>::infinity());
    for (int k = 0; k < fine.dims[2]; ++k)
        for (int j = 0; j < fine.dims[1]; ++j)
            for (int i = 0; i < fine.dims[0]; ++i) {
                float& to = c.limit[c.index(i / 3, j / 3, k / 3)];
                to = std::min(to, fine.limit[fine.index(i, j, k)]);
            }
    return c;
}

}  // namespace

CellSizeLimits noSizeLimits(const std::array<int, 3>& points) {
    CellSizeLimits l;
    l.dims = levelDims(points, 1);
    l.limit.assign(static_cast<std::size_t>(l.dims[0]) * l.dims[1] * l.dims[2], std::numeric_limits<float>::infinity());
    return l;
}

CellSizeLimits labelSizeLimits(const Labels& labels, const std::vector<std::pair<std::int32_t, double>>& sizes) {
    CellSizeLimits out = noSizeLimits(labels.grid.dims);
    if (sizes.empty()) return out;
    auto sizeOf = [&](std::int32_t label) {
        float s = std::numeric_limits<float>::infinity();
        for (const auto& [l, v] : sizes)
            if (l == label) s = std::min(s, static_cast<float>(v));
        return s;
    };
    const auto& d = out.dims;
    tbb::parallel_for(0, d[2], [&](int ck) {
        for (int cj = 0; cj < d[1]; ++cj)
            for (int ci = 0; ci < d[0]; ++ci) {
                float limit = std::numeric_limits<float>::infinity();
                std::int32_t last = 0;  // background has no size
                for (int k = 3 * ck; k < 3 * ck + 3; ++k)
                    for (int j = 3 * cj; j < 3 * cj + 3; ++j)
                        for (int i = 3 * ci; i < 3 * ci + 3; ++i) {
                            if (!labels.grid.contains(i, j, k)) continue;
                            const std::int32_t m = labels.material[labels.grid.index(i, j, k)];
                            if (m == last) continue;
                            last = m;
                            limit = std::min(limit, sizeOf(m));
                        }
                out.limit[out.index(ci, cj, ck)] = limit;
            }
    });
    return out;
}

RequestMasks requestsForLimits(const CellSizeLimits& limits, const std::array<int, 3>& points, double finestWidth,
                               int top) {
    RequestMasks masks = emptyRequests(points, top);
    CellSizeLimits level = limits;
    double width = 3 * finestWidth;
    for (int l = 1; l <= top; ++l, width *= 3) {
        if (l > 1) level = coarser(level);
        auto& m = masks[static_cast<std::size_t>(l)];
        for (std::size_t c = 0; c < m.size() && c < level.limit.size(); ++c) m[c] = wider(width, level.limit[c]) ? 1 : 0;
    }
    return masks;
}

int levelForMaxSize(double maxSize, double finestWidth, int maxLevel) {
    int level = 0;
    for (double w = 3 * finestWidth; level < maxLevel && !(w > maxSize * (1 + 1e-6)); w *= 3) ++level;
    return level;
}

}  // namespace isohex::octree

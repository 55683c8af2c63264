#include "isohex/pipeline/Thickness.hpp"

#include <cmath>
#include <functional>

#include <openvdb/openvdb.h>
#include <openvdb/tools/FastSweeping.h>
#include <tbb/parallel_for.h>

namespace isohex::pipeline {

namespace {

using octree::Labels;

// A fog grid over the labels' points (every voxel active): 1 where `in`, else 0.
openvdb::FloatGrid::Ptr fogOf(const Labels& labels, const std::function<bool(std::size_t)>& in) {
    const auto& d = labels.grid.dims;
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->denseFill(openvdb::CoordBBox({0, 0, 0}, {d[0] - 1, d[1] - 1, d[2] - 1}), 0.0f, true);
    auto acc = grid->getAccessor();
    for (int k = 0; k < d[2]; ++k)
        for (int j = 0; j < d[1]; ++j)
            for (int i = 0; i < d[0]; ++i)
                if (in(labels.grid.index(i, j, k))) acc.setValueOnly({i, j, k}, 1.0f);
    return grid;
}

// Distance (grid steps) from every point to the nearest point of `set`, by
// fast sweeping from the fog's half-way surface; +infinity when `set` is empty.
std::vector<float> distanceTo(const Labels& labels, const std::function<bool(std::size_t)>& set, bool& empty) {
    const auto fog = fogOf(labels, set);
    std::vector<float> out(labels.grid.size(), std::numeric_limits<float>::infinity());
    empty = true;
    for (auto it = fog->cbeginValueOn(); it; ++it)
        if (*it > 0.5f) {
            empty = false;
            break;
        }
    if (empty) return out;
    const auto sdf = openvdb::tools::fogToSdf(*fog, 0.5f);
    const auto& d = labels.grid.dims;
    tbb::parallel_for(0, d[2], [&](int k) {
        auto acc = sdf->getConstAccessor();
        for (int j = 0; j < d[1]; ++j)
            for (int i = 0; i < d[0]; ++i) {
                const std::size_t p = labels.grid.index(i, j, k);
                // the zero set lies half a step off the set's points
                out[p] = set(p) ? 0.0f : std::max(0.0f, acc.getValue({i, j, k}) + 0.5f);
            }
    });
    return out;
}

// Grid points with a face neighbour of another label (off the grid: background).
std::vector<std::uint8_t> boundaryPoints(const Labels& labels) {
    const auto& d = labels.grid.dims;
    std::vector<std::uint8_t> b(labels.grid.size(), 0);
    tbb::parallel_for(0, d[2], [&](int k) {
        for (int j = 0; j < d[1]; ++j)
            for (int i = 0; i < d[0]; ++i) {
                const std::int32_t m = labels.material[labels.grid.index(i, j, k)];
                // off the grid counts as the same label: the box is not a surface
                const auto differs = [&](int a, int b2, int c) {
                    return a >= 0 && b2 >= 0 && c >= 0 && a < d[0] && b2 < d[1] && c < d[2] && labels.at(a, b2, c) != m;
                };
                b[labels.grid.index(i, j, k)] = differs(i - 1, j, k) || differs(i + 1, j, k) || differs(i, j - 1, k) ||
                                                differs(i, j + 1, k) || differs(i, j, k - 1) || differs(i, j, k + 1);
            }
    });
    return b;
}

}  // namespace

octree::RequestMasks thicknessRequests(const Labels& labels, int top) {
    const auto& points = labels.grid.dims;
    octree::RequestMasks masks = octree::emptyRequests(points, top);
    const std::vector<std::uint8_t> boundary = boundaryPoints(labels);
    bool noBoundary = false;
    const std::vector<float> toBoundary = distanceTo(labels, [&](std::size_t p) { return boundary[p] != 0; }, noBoundary);
    int width = 1;
    for (int l = 1; l <= top; ++l) {
        width *= 3;
        const auto r = static_cast<float>(width);
        // the erosion: material points at least r from the surface (half a step beyond the boundary points)
        auto inCore = [&](std::size_t p) {
            return labels.material[p] != 0 && (boundary[p] ? 0.5f : toBoundary[p] + 0.5f) >= r;
        };
        bool noCore = false;
        const std::vector<float> toCore = distanceTo(labels, inCore, noCore);
        const auto dims = octree::levelDims(points, l);
        auto& mask = masks[static_cast<std::size_t>(l)];
        tbb::parallel_for(0, dims[2], [&](int ck) {
            for (int k = ck * width; k < std::min(points[2], (ck + 1) * width); ++k)
                for (int j = 0; j < points[1]; ++j)
                    for (int i = 0; i < points[0]; ++i) {
                        const std::size_t p = labels.grid.index(i, j, k);
                        if (labels.material[p] == 0 || toCore[p] <= r) continue;  // background, or in the opening
                        mask[(static_cast<std::size_t>(ck) * dims[1] + static_cast<std::size_t>(j / width)) * dims[0] +
                             static_cast<std::size_t>(i / width)] = 1;
                    }
        });
    }
    return masks;
}

}  // namespace isohex::pipeline

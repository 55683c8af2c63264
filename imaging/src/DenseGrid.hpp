#pragma once
// Internal: bulk moves between dense x-fastest arrays and OpenVDB grids.
#include <cstdint>
#include <vector>

#include <openvdb/openvdb.h>

namespace isohex::imaging::detail {

// A grid whose voxels in `box` are all active and hold `data` (x fastest);
// everything else reads `background`. Leaves are filled in parallel, each by
// one thread, so no accessor is shared.
openvdb::FloatGrid::Ptr denseToGrid(const float* data, const openvdb::CoordBBox& box,
                                    float background, openvdb::math::Transform::Ptr transform);
openvdb::Int32Grid::Ptr denseToGrid(const std::int32_t* data, const openvdb::CoordBBox& box,
                                    std::int32_t background,
                                    openvdb::math::Transform::Ptr transform);

// The values of `box` as a dense x-fastest array (background where unset).
std::vector<float> gridToDense(const openvdb::FloatGrid& grid, const openvdb::CoordBBox& box);

inline std::size_t denseIndex(const openvdb::CoordBBox& box, const openvdb::Coord& c) {
    const openvdb::Coord d = box.dim();
    return static_cast<std::size_t>(c.x() - box.min().x()) +
           static_cast<std::size_t>(d.x()) *
               (static_cast<std::size_t>(c.y() - box.min().y()) +
                static_cast<std::size_t>(d.y()) * static_cast<std::size_t>(c.z() - box.min().z()));
}

}  // namespace isohex::imaging::detail

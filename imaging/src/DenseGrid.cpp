#include "DenseGrid.hpp"

#include <openvdb/tools/Dense.h>
#include <openvdb/tree/LeafManager.h>

namespace isohex::imaging::detail {
namespace {

template <class GridT>
typename GridT::Ptr fill(const typename GridT::ValueType* data, const openvdb::CoordBBox& box,
                         typename GridT::ValueType background,
                         openvdb::math::Transform::Ptr transform) {
    using TreeT = typename GridT::TreeType;
    auto grid = GridT::create(background);
    grid->setTransform(transform);
    if (box.empty()) return grid;
    // Allocates every leaf touching the box with the box's voxels active.
    grid->tree().denseFill(box, background, /*active=*/true);
    openvdb::tree::LeafManager<TreeT> leaves(grid->tree());
    leaves.foreach([&](typename TreeT::LeafNodeType& leaf, std::size_t) {
        for (auto it = leaf.beginValueOn(); it; ++it) it.setValue(data[denseIndex(box, it.getCoord())]);
    });
    return grid;
}

}  // namespace

openvdb::FloatGrid::Ptr denseToGrid(const float* data, const openvdb::CoordBBox& box,
                                    float background, openvdb::math::Transform::Ptr transform) {
    return fill<openvdb::FloatGrid>(data, box, background, std::move(transform));
}

openvdb::Int32Grid::Ptr denseToGrid(const std::int32_t* data, const openvdb::CoordBBox& box,
                                    std::int32_t background,
                                    openvdb::math::Transform::Ptr transform) {
    return fill<openvdb::Int32Grid>(data, box, background, std::move(transform));
}

std::vector<float> gridToDense(const openvdb::FloatGrid& grid, const openvdb::CoordBBox& box) {
    std::vector<float> out(static_cast<std::size_t>(box.volume()), grid.background());
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(box, out.data());
    openvdb::tools::copyToDense(grid, dense);
    return out;
}

}  // namespace isohex::imaging::detail

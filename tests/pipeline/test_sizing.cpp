// The adaptive mesher's thickness criterion and sizing image, on label grids
// and images built here: a thin plate and a thick block, and images whose
// voxels are finer and coarser than the tree's cells.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "isohex/imaging/Volume.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/pipeline/SizeImage.hpp"
#include "isohex/pipeline/Thickness.hpp"

using namespace isohex;

namespace {

// 81^3 points: a plate of label 1 four points thick (z 10..13) and a block of
// label 2 48 points thick (z 30..77), both over x, y 3..77.
octree::Labels plateAndBlock() {
    octree::Labels l;
    l.grid.dims = {81, 81, 81};
    l.material.assign(l.grid.size(), 0);
    for (int k = 0; k < 81; ++k)
        for (int j = 3; j < 78; ++j)
            for (int i = 3; i < 78; ++i)
                l.material[l.grid.index(i, j, k)] = (k >= 10 && k < 14) ? 1 : (k >= 30 && k < 78) ? 2 : 0;
    return l;
}

bool requested(const octree::RequestMasks& m, const std::array<int, 3>& points, int level, int i, int j, int k) {
    int w = 1;
    for (int l = 0; l < level; ++l) w *= 3;
    const auto d = octree::levelDims(points, level);
    return m[static_cast<std::size_t>(level)][(static_cast<std::size_t>(k / w) * d[1] + j / w) * d[0] + i / w] != 0;
}

imaging::Volume sizeVolume(const Vec3& origin, double spacing, int n, float value) {
    imaging::Volume v;
    v.spacing = {spacing, spacing, spacing};
    v.origin = origin;
    v.intensity = openvdb::FloatGrid::create(0.0f);
    v.intensity->setTransform(imaging::makeTransform(v.origin, v.spacing, v.direction));
    v.box = openvdb::CoordBBox({0, 0, 0}, {n - 1, n - 1, n - 1});
    v.intensity->denseFill(v.box, value, true);
    v.maxValue = value;
    return v;
}

}  // namespace

TEST(Thickness, APlateThinnerThanTwoCellsIsRefinedAtEveryLevelAThickBlockOnlyWhereCellsAreTooWide) {
    const octree::Labels l = plateAndBlock();
    const auto& p = l.grid.dims;
    const octree::RequestMasks m = pipeline::thicknessRequests(l, 3);
    ASSERT_EQ(m.size(), 4u);
    for (int level = 1; level <= 3; ++level) EXPECT_TRUE(requested(m, p, level, 40, 40, 11)) << "plate, level " << level;
    // the block is 48 steps thick: not thin for 3- and 9-step cells (below 6 and 18) away from its edges,
    // thin for 27-step cells (below 54)
    EXPECT_FALSE(requested(m, p, 1, 40, 40, 54));
    EXPECT_FALSE(requested(m, p, 2, 40, 40, 54));
    EXPECT_TRUE(requested(m, p, 3, 40, 40, 54));
    // background alone asks nothing
    EXPECT_FALSE(requested(m, p, 1, 40, 40, 22));
    // a box's corner is thin (no ball of radius 3 inside reaches it)
    EXPECT_TRUE(requested(m, p, 1, 3, 3, 30));
}

TEST(SizeImage, TheLimitIsTheSmallestSizeOverTheCellAndNothingOutsideTheImage) {
    octree::Grid g;
    g.dims = {27, 27, 27};
    // 2 mm voxels from (10, 10, 10): 2 mm everywhere, 0.5 mm at voxel (2, 2, 2) = world (14, 14, 14), 0 at (4, 4, 4)
    imaging::Volume fine = sizeVolume({10, 10, 10}, 2.0, 5, 2.0f);
    fine.intensity->tree().setValue({2, 2, 2}, 0.5f);
    fine.intensity->tree().setValue({4, 4, 4}, 0.0f);
    const octree::CellSizeLimits s = pipeline::sizeImageLimits(fine, g);
    EXPECT_EQ(s.limit[s.index(4, 4, 4)], 0.5f);  // grid coordinate 14 is in cell floor(14.5 / 3) = 4
    EXPECT_EQ(s.limit[s.index(3, 3, 3)], 2.0f);
    EXPECT_EQ(s.limit[s.index(0, 0, 0)], std::numeric_limits<float>::infinity());
    EXPECT_EQ(s.limit[s.index(6, 6, 6)], std::numeric_limits<float>::infinity());  // (18,18,18): size 0 asks nothing
    // one 10 mm voxel centred at (13, 13, 13): cell 3's centre (10, 10, 10) lies in it, its voxel centre does not
    const imaging::Volume coarse = sizeVolume({13, 13, 13}, 10.0, 1, 4.0f);
    const octree::CellSizeLimits c = pipeline::sizeImageLimits(coarse, g);
    EXPECT_EQ(c.limit[c.index(3, 3, 3)], 4.0f);
    EXPECT_EQ(c.limit[c.index(4, 4, 4)], 4.0f);
    EXPECT_EQ(c.limit[c.index(1, 1, 1)], std::numeric_limits<float>::infinity());
}

TEST(Thickness, TheGridsBoxIsNotASurface) {
    // label 1 fills z < 40 up to the box on five sides: 40 steps thick, its only surface the face z = 40
    octree::Labels l;
    l.grid.dims = {81, 81, 81};
    l.material.assign(l.grid.size(), 0);
    for (int k = 0; k < 40; ++k)
        for (int j = 0; j < 81; ++j)
            for (int i = 0; i < 81; ++i) l.material[l.grid.index(i, j, k)] = 1;
    const auto& p = l.grid.dims;
    const octree::RequestMasks m = pipeline::thicknessRequests(l, 3);
    // the material goes on past the box: not thin for any cell, not at the box's corners and edges either
    for (int level = 1; level <= 3; ++level) {
        EXPECT_FALSE(requested(m, p, level, 0, 0, 0)) << "the box's corner, level " << level;
        EXPECT_FALSE(requested(m, p, level, 40, 0, 20)) << "the box's face, level " << level;
        EXPECT_FALSE(requested(m, p, level, 0, 0, 39)) << "where the surface meets the box, level " << level;
    }
    // a plate 4 steps thick across the box (x 39..42) is thin for 3-step cells, at the box too
    for (int k = 0; k < 81; ++k)
        for (int j = 0; j < 81; ++j)
            for (int i = 0; i < 81; ++i) l.material[l.grid.index(i, j, k)] = (i >= 39 && i < 43) ? 1 : 0;
    const octree::RequestMasks thin = pipeline::thicknessRequests(l, 1);
    EXPECT_TRUE(requested(thin, p, 1, 40, 40, 40));
    EXPECT_TRUE(requested(thin, p, 1, 40, 0, 0));
}

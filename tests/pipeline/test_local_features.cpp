// LocalFeatures on hand-made label grids: the shape next to a point and the
// features finer than an element (specks, pockets, one-point strands and
// tunnels of a few points), with their positions, volumes and replacements;
// larger or thicker shapes are never features.
#include <gtest/gtest.h>

#include "isohex/pipeline/LocalFeatures.hpp"

namespace isohex::pipeline {
namespace {

// A 16^3 grid of step 2 (cell volume 8) at origin (10, 0, 0), all background.
octree::Labels emptyGrid() {
    octree::Labels l;
    l.grid.origin = {10, 0, 0};
    l.grid.axes = {{{2, 0, 0}, {0, 2, 0}, {0, 0, 2}}};
    l.grid.dims = {16, 16, 16};
    l.material.assign(l.grid.size(), 0);
    return l;
}

void fill(octree::Labels& l, std::array<int, 3> lo, std::array<int, 3> hi, std::int32_t m) {
    for (int k = lo[2]; k < hi[2]; ++k)
        for (int j = lo[1]; j < hi[1]; ++j)
            for (int i = lo[0]; i < hi[0]; ++i) l.material[l.grid.index(i, j, k)] = m;
}

TEST(LocalFeatures, OnePointSpeckIsFoundWithPositionVolumeAndReplacement) {
    octree::Labels l = emptyGrid();
    fill(l, {2, 2, 2}, {8, 14, 14}, 1);
    fill(l, {10, 7, 7}, {11, 8, 8}, 1);  // one point, two points off the block
    const LocalFeatures f(l, nullptr);
    const Vec3 at = l.grid.point(10, 7, 7);
    EXPECT_EQ(f.shapeAt(at), LocalShape::Speck);
    const std::vector<FineFeature> found = f.featuresAt(at);
    ASSERT_EQ(found.size(), 1u);
    EXPECT_EQ(found[0].shape, LocalShape::Speck);
    EXPECT_EQ(found[0].points, std::vector<std::size_t>{l.grid.index(10, 7, 7)});
    EXPECT_EQ(found[0].material, 1);
    EXPECT_EQ(found[0].replacedBy, 0);
    EXPECT_DOUBLE_EQ(found[0].volume, 8.0);
    EXPECT_DOUBLE_EQ(found[0].at[0], 30.0);
    EXPECT_DOUBLE_EQ(found[0].at[1], 14.0);
}

TEST(LocalFeatures, TwoPointPocketInsideAMaterialIsFound) {
    octree::Labels l = emptyGrid();
    fill(l, {2, 2, 2}, {14, 14, 14}, 3);
    fill(l, {7, 7, 7}, {9, 8, 8}, 0);
    const LocalFeatures f(l, nullptr);
    const std::vector<FineFeature> found = f.featuresAt(l.grid.point(7.4, 7, 7));
    ASSERT_EQ(found.size(), 1u);
    EXPECT_EQ(found[0].shape, LocalShape::Pocket);
    EXPECT_EQ(found[0].points.size(), 2u);
    EXPECT_EQ(found[0].replacedBy, 3);
    EXPECT_DOUBLE_EQ(found[0].volume, 16.0);
    EXPECT_DOUBLE_EQ(found[0].at[0], 10 + 2 * 7.5);
}

TEST(LocalFeatures, ShortTunnelThroughAPlateIsFoundWhole) {
    octree::Labels l = emptyGrid();
    fill(l, {2, 2, 6}, {14, 14, 10}, 1);  // four points thick
    fill(l, {7, 7, 6}, {8, 8, 10}, 0);    // a hole one point wide through it
    const LocalFeatures f(l, nullptr);
    const Vec3 at = l.grid.point(7, 7, 6);  // next to one end
    EXPECT_EQ(f.shapeAt(at), LocalShape::Tunnel);
    const std::vector<FineFeature> found = f.featuresAt(at);
    ASSERT_EQ(found.size(), 1u);
    EXPECT_EQ(found[0].shape, LocalShape::Tunnel);
    EXPECT_EQ(found[0].points.size(), 4u);  // all four, not only those in the 3x3x3 block
    EXPECT_EQ(found[0].replacedBy, 1);
}

TEST(LocalFeatures, LongStrandAndThinSheetAreNotFeatures) {
    octree::Labels l = emptyGrid();
    fill(l, {2, 7, 7}, {14, 8, 8}, 1);   // a strand 12 points long
    fill(l, {2, 2, 11}, {14, 14, 12}, 2);  // a sheet one point thick
    const LocalFeatures f(l, nullptr);
    EXPECT_EQ(f.shapeAt(l.grid.point(7, 7, 7)), LocalShape::Strand);
    EXPECT_TRUE(f.featuresAt(l.grid.point(7, 7, 7)).empty());
    EXPECT_EQ(f.shapeAt(l.grid.point(7, 4, 11)), LocalShape::ThinSheet);
    EXPECT_TRUE(f.featuresAt(l.grid.point(7, 4, 11)).empty());
}

TEST(LocalFeatures, ControlBallHasBoundaryInteriorAndTripleLineButNoFeature) {
    octree::Labels l = emptyGrid();
    fill(l, {2, 2, 2}, {14, 14, 14}, 1);
    fill(l, {8, 2, 2}, {14, 14, 14}, 2);
    const LocalFeatures f(l, nullptr);
    EXPECT_EQ(f.shapeAt(l.grid.point(4, 4, 4)), LocalShape::Interior);
    EXPECT_EQ(f.shapeAt(l.grid.point(5, 2, 7)), LocalShape::Boundary);
    EXPECT_EQ(f.shapeAt(l.grid.point(8, 2, 7)), LocalShape::TripleLine);
    for (int k = 1; k < 15; ++k)
        for (int i = 1; i < 15; ++i) EXPECT_TRUE(f.featuresAt(l.grid.point(i, 2, k)).empty()) << i << " " << k;
}

}  // namespace
}  // namespace isohex::pipeline

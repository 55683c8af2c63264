// LoadOptions::region and summarizeScan: a region read keeps the file's voxel
// indices and values (streamed from .nii, .nii.gz and .mha, read whole and
// cropped from .nrrd), and the slab-by-slab summary makes the whole
// scan's decisions as select() does on the whole volume.
#include <gtest/gtest.h>

#include <cmath>

#include "TestSupport.hpp"
#include "isohex/imaging/ScanSummary.hpp"
#include "isohex/imaging/Selection.hpp"
#include "isohex/imaging/Volume.hpp"

using namespace isohex::imaging;
using namespace isohex::imaging::test;

namespace {

const Dims kDims{21, 17, 30};

std::vector<float> ballValues() {
    std::vector<float> v;
    for (int z = 0; z < kDims[2]; ++z)
        for (int y = 0; y < kDims[1]; ++y)
            for (int x = 0; x < kDims[0]; ++x) {
                const double r = std::sqrt((x - 10.0) * (x - 10.0) + (y - 8.0) * (y - 8.0) + (z - 17.0) * (z - 17.0));
                v.push_back(static_cast<float>(100.0 - 9.0 * r + 0.25 * x));
            }
    return v;
}

Geometry geometry() {
    Geometry g;
    g.origin = {-3.0, 5.5, 12.0};
    g.spacing = {0.8, 0.9, 1.1};
    return g;
}

}  // namespace

TEST(RegionRead, ARegionHasTheWholeReadsValuesAtTheSameIndices) {
    const fs::path dir = scratchDir("region_read");
    const std::vector<float> v = ballValues();
    const openvdb::CoordBBox region(openvdb::Coord(0, 0, 9), openvdb::Coord(20, 16, 19));
    for (const std::string name : {"ball.nii", "ball.mha", "ball.nii.gz", "ball.nrrd"}) {
        writeImage(dir / name, kDims, v, geometry());
        LoadOptions lo;
        const Volume whole = loadVolume(dir / name, lo);
        lo.region = region;
        const Volume part = loadVolume(dir / name, lo);
        EXPECT_EQ(part.box, region) << name;
        EXPECT_EQ(part.fileDims, openvdb::Coord(kDims[0], kDims[1], kDims[2])) << name;
        // ITK's NIfTI reader reads a region of a .nii.gz too, decompressing from
        // the file's start (summarizeScan does not read it slab by slab: one
        // decompression per slab); its NRRD reader reads the whole file
        const bool streams = name != "ball.nrrd";
        EXPECT_EQ(part.regionStreamed, streams) << name;
        EXPECT_EQ(part.transform(), whole.transform()) << name;
        for (int z = region.min().z(); z <= region.max().z(); ++z)
            for (int y = 0; y < kDims[1]; ++y)
                for (int x = 0; x < kDims[0]; ++x) {
                    const openvdb::Coord c(x, y, z);
                    ASSERT_EQ(part.intensity->tree().getValue(c), whole.intensity->tree().getValue(c)) << name;
                }
        EXPECT_FALSE(part.intensity->tree().isValueOn(openvdb::Coord(0, 0, 8))) << name;
    }
}

TEST(RegionRead, TheSummaryMakesSelectsWholeScanDecisions) {
    const fs::path dir = scratchDir("region_summary");
    writeImage(dir / "ball.nii", kDims, ballValues(), geometry());
    writeImage(dir / "ball.nii.gz", kDims, ballValues(), geometry());
    const Volume whole = loadVolume(dir / "ball.nii");
    const Selection sel = select(whole);  // Otsu's iso value
    // few voxels a read: many slabs of whole slices
    const auto sum = summarizeScan(dir / "ball.nii", {}, {}, 2 * kDims[0] * kDims[1]);
    ASSERT_TRUE(sum.has_value());
    EXPECT_EQ(sum->slabReads, 3 * 16);  // 3 passes: one slice, then 15 slabs of 2
    EXPECT_EQ(sum->dims, openvdb::Coord(kDims[0], kDims[1], kDims[2]));
    EXPECT_TRUE(sum->isoFromOtsu);
    EXPECT_EQ(sum->iso, *sel.iso);
    EXPECT_EQ(sum->minValue, whole.minValue);
    EXPECT_EQ(sum->maxValue, whole.maxValue);
    EXPECT_EQ(sum->selectedVoxels, sel.materials.front().voxels);
    openvdb::CoordBBox solid;
    std::array<std::vector<std::int64_t>, 3> perLayer;
    for (int a = 0; a < 3; ++a) perLayer[a].assign(static_cast<std::size_t>(kDims[a]), 0);
    const auto& field = sel.materials.front().field.grid().tree();
    for (int z = 0; z < kDims[2]; ++z)
        for (int y = 0; y < kDims[1]; ++y)
            for (int x = 0; x < kDims[0]; ++x)
                if (field.getValue(openvdb::Coord(x, y, z)) < 0) {
                    solid.expand(openvdb::Coord(x, y, z));
                    ++perLayer[0][x], ++perLayer[1][y], ++perLayer[2][z];
                }
    EXPECT_EQ(sum->solid, solid);
    EXPECT_EQ(sum->perLayer, perLayer);
    // a given iso value; and a file that does not stream gives no summary
    SelectOptions so;
    so.iso = 50.0;
    EXPECT_EQ(summarizeScan(dir / "ball.nii", {}, so)->selectedVoxels, select(whole, so).materials.front().voxels);
    EXPECT_FALSE(summarizeScan(dir / "ball.nii.gz", {}, {}).has_value());
}

// Hostile DICOM: files whose tags lie (Pixel Data, BitsAllocated, Image
// Orientation, Pixel Spacing), series with a slice twice or of another size,
// and a lone 2-D slice are refused with one error naming the file, the fault
// and what to do. The files are written by ITK and edited through GDCM here.
#include <gtest/gtest.h>

#include <cstring>

#include "TestSupport.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/imaging/Volume.hpp"

using namespace isohex::imaging;
using namespace isohex::imaging::test;

namespace {

const Dims kDims{10, 9, 8};
const std::string kUid = "1.2.826.0.1.3680043.2.1125.99.77";

std::vector<std::int16_t> voxels(const Dims& d) {
    std::vector<std::int16_t> v(std::size_t(d[0]) * d[1] * d[2]);
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<std::int16_t>(100 + i % 97);
    return v;
}

std::string us(std::uint16_t value) {
    std::string b(2, '\0');
    std::memcpy(b.data(), &value, 2);
    return b;
}

}  // namespace

TEST(HostileDicom, PixelDataThatIsNotRowsTimesColumnsTimesBitsIsRefused) {
    // GDCM padded short Pixel Data and ITK read a lying BitsAllocated's
    // bytes as voxels, without a word.
    const auto dir = scratchDir("dicompixels");
    writeDicomSeries(dir / "s", kDims, voxels(kDims), Geometry{}, kUid);
    ASSERT_EQ(loadVolume(dir / "s").dims(), openvdb::Coord(10, 9, 8));
    const auto slice = dir / "s" / "slice4.dcm";
    const std::string original = readAll(slice);
    setDicomElement(slice, 0x7fe0, 0x0010, std::string(90, '\1'));  // half of 10 x 9 x 16 bits
    expectError([&] { loadVolume(dir / "s"); }, {"slice4.dcm", "Pixel Data holds 90 bytes", "need 180", "short"});
    writeBytes(slice, original);
    setDicomElement(slice, 0x0028, 0x0100, us(32));  // BitsAllocated 32 over 16-bit data
    expectError([&] { loadVolume(dir / "s"); }, {"slice4.dcm", "BitsAllocated 32", "need 360", "export"});
    writeBytes(slice, original);
    setDicomElement(slice, 0x0028, 0x0100, us(12));
    expectError([&] { loadVolume(dir / "s"); }, {"slice4.dcm", "BitsAllocated is 12"});
    // A multi-frame file read on its own is checked alike.
    writeMultiFrameDicom(dir / "volume.dcm", kDims, voxels(kDims), Geometry{});
    setDicomElement(dir / "volume.dcm", 0x0028, 0x0100, us(8));  // with BitsStored and HighBit to match
    setDicomElement(dir / "volume.dcm", 0x0028, 0x0101, us(8));
    setDicomElement(dir / "volume.dcm", 0x0028, 0x0102, us(7));
    expectError([&] { loadVolume(dir / "volume.dcm"); }, {"volume.dcm", "BitsAllocated 8", "need 720"});
    fs::remove_all(dir);
}

TEST(HostileDicom, OrientationAndSpacingTagsThatSayNothingAreRefused) {
    // ITK put identity axes for an all-zero Image Orientation (Patient) and
    // 1 mm for a Pixel Spacing of 0.
    const auto dir = scratchDir("dicomgeometry");
    writeDicomSeries(dir / "s", kDims, voxels(kDims), Geometry{}, kUid);
    const auto slice = dir / "s" / "slice0.dcm";
    const std::string original = readAll(slice);
    setDicomElement(slice, 0x0020, 0x0037, "0\\0\\0\\0\\0\\0 ");
    expectError([&] { loadVolume(dir / "s"); }, {"slice0.dcm", "Image Orientation (Patient) is '0\\0\\0\\0\\0\\0",
                                                 "perpendicular unit vectors"});
    writeBytes(slice, original);
    setDicomElement(slice, 0x0028, 0x0030, "0\\0 ");
    expectError([&] { loadVolume(dir / "s"); }, {"slice0.dcm", "Pixel Spacing is '0\\0", "positive"});
    fs::remove_all(dir);
}

TEST(HostileDicom, TwoSlicesAtOnePositionAreRefused) {
    // Only GDCM's console said so; the slices were stacked as neighbours.
    const auto dir = scratchDir("dicomtwice");
    writeDicomSeries(dir / "s", kDims, voxels(kDims), Geometry{}, kUid, 1, 0, "a");
    writeDicomSeries(dir / "s", kDims, voxels(kDims), Geometry{}, kUid, 1, 0, "b");
    expectError([&] { loadVolume(dir / "s"); }, {"s", "lie at the same position", "Remove the extra files"});
    fs::remove_all(dir);
}

TEST(HostileDicom, ASliceOfAnotherSizeIsNamedNotCalledMissing) {
    // A 32 x 32 slice among 24 x 24 ones went into a series of its own and
    // the gap it left was reported as a missing slice.
    const auto dir = scratchDir("dicomsize");
    const Dims dims{24, 24, 6};
    Geometry g;
    g.spacing = {1, 1, 2};
    writeDicomSeries(dir / "s", dims, voxels(dims), g, kUid);
    fs::remove(dir / "s" / "slice3.dcm");
    Geometry at3 = g;
    at3.origin[2] = 3 * 2.0;
    writeDicomSeries(dir / "s", {32, 32, 1}, voxels({32, 32, 1}), at3, kUid, 1, 0, "odd");
    const std::string msg = expectError([&] { loadVolume(dir / "s"); },
                                        {"odd0.dcm", "32 x 32", "24 x 24", "slice size differs"});
    EXPECT_EQ(msg.find("missing"), std::string::npos) << msg;
    fs::remove_all(dir);
}

TEST(HostileDicom, ALoneTwoDimensionalSliceIsRefusedAsA2DNiftiIs) {
    // One slice file was meshed as a volume one voxel thick.
    const auto dir = scratchDir("dicomlone");
    writeDicomSeries(dir / "s", kDims, voxels(kDims), Geometry{}, kUid);
    expectError([&] { loadVolume(dir / "s" / "slice2.dcm"); }, {"slice2.dcm", "2-D image", "needs a 3-D volume"});
    fs::remove_all(dir);
}

TEST(HostileDicom, AFileCutInsideItsHeaderIsRefusedBeforeGdcmAsserts) {
    // Debian's GDCM stopped the process on an assertion for a file ending
    // inside an element before its Pixel Data (the job isolation only named
    // the file). Every cut from the end of the preamble to the Pixel Data.
    const auto dir = scratchDir("dicomheadcut");
    writeDicomSeries(dir / "s", kDims, voxels(kDims), Geometry{}, kUid);
    const std::string whole = readAll(dir / "s" / "slice5.dcm");
    const std::size_t pixels = whole.rfind(std::string("\xe0\x7f\x10\x00", 4));
    ASSERT_NE(pixels, std::string::npos);
    for (std::size_t keep = 133; keep < pixels; keep += 3) {
        SCOPED_TRACE(keep);
        writeBytes(dir / "cut.dcm", whole.substr(0, keep));
        const std::string msg = expectError([&] { loadVolume(dir / "cut.dcm"); }, {"cut.dcm"});
        EXPECT_TRUE(msg.find("truncated") != std::string::npos || msg.find("damaged") != std::string::npos) << msg;
    }
    writeBytes(dir / "s" / "slice5.dcm", whole.substr(0, 150));  // inside the meta group
    expectError([&] { loadVolume(dir / "s"); }, {"slice5.dcm", "truncated inside its header", "copy or export"});
    fs::remove_all(dir);
}

// Hostile scan headers: a header (NRRD, MetaImage, NIfTI) that lies about its
// data or points elsewhere is refused with one error naming the file, the
// fault and what to do; nothing it points at outside its folder is read.
// Every hostile file is made here, small, from a valid one.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include <sys/stat.h>
#include <zlib.h>

#include "TestSupport.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"
#include "isohex/imaging/Volume.hpp"

using namespace isohex::imaging;
using namespace isohex::imaging::test;

namespace {

const Dims kDims{10, 9, 8};
constexpr int kVoxels = 10 * 9 * 8;

// 720 bytes of uint8 voxels: a ramp.
std::string rawVoxels() {
    std::string v(kVoxels, '\0');
    for (int i = 0; i < kVoxels; ++i) v[std::size_t(i)] = static_cast<char>(i % 97);
    return v;
}

std::string nrrdHeader(const std::string& dataFile, const std::string& extra = "") {
    return "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 10 9 8\nencoding: raw\n" + extra + "data file: " + dataFile +
           "\n";
}

std::string metaHeader(const std::string& dataFile, const std::string& extra = "") {
    return "ObjectType = Image\nNDims = 3\nDimSize = 10 9 8\nElementType = MET_UCHAR\n" + extra +
           "ElementDataFile = " + dataFile + "\n";
}

LoadOptions allowingOutside() {
    LoadOptions o;
    o.allowDataOutside = true;
    return o;
}

// A NIfTI-1 file of kDims int16 voxels (value = index % 97) as bytes, with
// pixdim 1 and an identity sform; the tests lie in it afterwards.
std::string niftiBytes() {
    std::string h(352, '\0');
    auto put = [&](int at, auto v) { std::memcpy(h.data() + at, &v, sizeof v); };
    put(0, std::int32_t(348));
    const std::int16_t dim[8] = {3, 10, 9, 8, 1, 1, 1, 1};
    std::memcpy(h.data() + 40, dim, sizeof dim);
    put(70, std::int16_t(4));   // int16
    put(72, std::int16_t(16));  // bitpix
    const float pixdim[8] = {1, 1, 1, 1, 0, 0, 0, 0};
    std::memcpy(h.data() + 76, pixdim, sizeof pixdim);
    put(108, 352.0f);
    put(112, 1.0f);  // scl_slope
    put(254, std::int16_t(1));  // sform_code
    for (int r = 0; r < 3; ++r) put(280 + 16 * r + 4 * r, 1.0f);
    std::memcpy(h.data() + 344, "n+1", 4);
    std::string data(std::size_t(kVoxels) * 2, '\0');
    for (int i = 0; i < kVoxels; ++i) {
        const auto v = static_cast<std::int16_t>(100 + i % 97);
        std::memcpy(data.data() + 2 * i, &v, 2);
    }
    return h + data;
}

template <class T>
std::string with(std::string bytes, int at, T value) {
    std::memcpy(bytes.data() + at, &value, sizeof value);
    return bytes;
}

}  // namespace

TEST(HostileHeaders, NrrdDataFilesMustBeRegularFilesInTheHeadersFolder) {
    // teem followed "data file" anywhere: /etc/passwd by '../../..' or an
    // absolute path, /dev/urandom, the header itself: their bytes were meshed.
    const auto dir = scratchDir("nrrdplace");
    fs::create_directories(dir / "scan" / "sub");
    writeBytes(dir / "outside.raw", rawVoxels());
    writeBytes(dir / "outside1.raw", rawVoxels());
    writeBytes(dir / "scan" / "scan.raw", rawVoxels());
    writeBytes(dir / "scan" / "sub" / "below.raw", rawVoxels());
    ASSERT_EQ(mkfifo((dir / "scan" / "pipe.raw").c_str(), 0600), 0);
    fs::create_symlink(dir / "outside.raw", dir / "scan" / "link.raw");
    const auto header = dir / "scan" / "scan.nhdr";
    auto refused = [&](const std::string& text, const std::vector<std::string>& pieces, const LoadOptions& o = {}) {
        SCOPED_TRACE(text);
        writeBytes(header, text);
        std::vector<std::string> want = pieces;
        want.push_back("scan.nhdr");
        return expectError([&] { loadVolume(header, o); }, want);
    };
    const std::string absolute = (dir / "outside.raw").string();
    for (const std::string& name : {std::string("../outside.raw"), absolute, std::string("link.raw")}) {
        const std::string msg = refused(nrrdHeader(name), {name, "outside the header's folder", "allow data outside"});
        EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
        // Allowed explicitly, the same header reads the outside file.
        EXPECT_EQ(loadVolume(header, allowingOutside()).dims(), openvdb::Coord(10, 9, 8)) << name;
    }
    // Never a device, a pipe, a folder, the header itself or nothing, even when allowed.
    for (const LoadOptions& o : {LoadOptions{}, allowingOutside()}) {
        refused(nrrdHeader("/dev/zero"), {"'/dev/zero' is /dev/zero, a device"}, o);
        refused(nrrdHeader("/dev/urandom"), {"/dev/urandom, a device"}, o);
        refused(nrrdHeader("pipe.raw"), {"pipe.raw", "a named pipe"}, o);
        refused(nrrdHeader("sub"), {"'sub' is a directory"}, o);
        refused(nrrdHeader("scan.nhdr"), {"the header itself"}, o);
        refused(nrrdHeader("gone.raw"), {"gone.raw", "missing"}, o);
    }
    // A LIST and a pattern are checked file by file.
    refused("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 10 9 8\nencoding: raw\ndata file: LIST 2\n"
            "scan.raw\n../outside.raw\n",
            {"../outside.raw", "outside the header's folder"});
    refused(nrrdHeader("../outside%d.raw 1 1 1"), {"outside1.raw", "outside the header's folder"});
    // A negative byte skip below -1 shifted the data without a word.
    refused(nrrdHeader("scan.raw", "byte skip: -2\n"), {"byte skip is -2", "-1 or more"});
    // Inside the folder or below it is read.
    writeBytes(header, nrrdHeader("scan.raw"));
    EXPECT_EQ(loadVolume(header).dims(), openvdb::Coord(10, 9, 8));
    writeBytes(header, nrrdHeader("sub/below.raw"));
    EXPECT_EQ(loadVolume(header).dims(), openvdb::Coord(10, 9, 8));
    fs::remove_all(dir);
}

TEST(HostileHeaders, MetaImageDataFilesMustBeRegularFilesInTheHeadersFolder) {
    const auto dir = scratchDir("mhdplace");
    fs::create_directories(dir / "scan" / "sub");
    writeBytes(dir / "outside.raw", rawVoxels());
    writeBytes(dir / "scan" / "scan.raw", rawVoxels());
    const auto header = dir / "scan" / "scan.mhd";
    auto refused = [&](const std::string& text, const std::vector<std::string>& pieces, const LoadOptions& o = {}) {
        SCOPED_TRACE(text);
        writeBytes(header, text);
        std::vector<std::string> want = pieces;
        want.push_back("scan.mhd");
        expectError([&] { loadVolume(header, o); }, want);
    };
    refused(metaHeader("../outside.raw"), {"'../outside.raw'", "outside the header's folder", "allow data outside"});
    refused(metaHeader((dir / "outside.raw").string()), {"outside the header's folder"});
    writeBytes(header, metaHeader("../outside.raw"));
    EXPECT_EQ(loadVolume(header, allowingOutside()).dims(), openvdb::Coord(10, 9, 8));
    for (const LoadOptions& o : {LoadOptions{}, allowingOutside()}) {
        // /dev/zero and a folder were called "missing"
        refused(metaHeader("/dev/zero"), {"/dev/zero, a device"}, o);
        refused(metaHeader("sub"), {"'sub' is a directory"}, o);
        refused(metaHeader("scan.mhd"), {"the header itself", "LOCAL"}, o);
    }
    std::string list = "ObjectType = Image\nNDims = 3\nDimSize = 10 9 8\nElementType = MET_UCHAR\nElementDataFile = LIST 2D\n";
    for (int z = 0; z < 8; ++z) {
        writeBytes(dir / "scan" / ("s" + std::to_string(z) + ".raw"), rawVoxels().substr(0, 90));
        list += z == 5 ? "../outside.raw\n" : "s" + std::to_string(z) + ".raw\n";
    }
    refused(list, {"'../outside.raw'", "outside the header's folder"});
    // HeaderSize below -1 is no place in the file.
    refused(metaHeader("scan.raw", "HeaderSize = -2\n"), {"HeaderSize is -2"});
    // Without ElementDataFile MetaIO aborted the process (a fortified read past its buffer).
    refused("ObjectType = Image\nNDims = 3\nDimSize = 10 9 8\nElementType = MET_UCHAR\n", {"no ElementDataFile"});
    writeBytes(header, metaHeader("scan.raw"));
    EXPECT_EQ(loadVolume(header).dims(), openvdb::Coord(10, 9, 8));
    fs::remove_all(dir);
}

TEST(HostileHeaders, ShearedAxesAreRefusedAlikeInEveryFormat) {
    // NRRD space directions and a MetaImage TransformMatrix that are not
    // perpendicular were read as they are (the mesh did not follow the
    // isosurface); a sheared NIfTI is refused. All now say the same.
    const auto dir = scratchDir("shear");
    writeBytes(dir / "scan.raw", rawVoxels());
    const std::string nrrd = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 10 9 8\nencoding: raw\nspace: left-posterior-superior\n";
    writeBytes(dir / "shear.nhdr", nrrd + "space directions: (1,0,0) (0.5,1,0) (0,0,1)\ndata file: scan.raw\n");
    expectError([&] { loadVolume(dir / "shear.nhdr"); }, {"shear.nhdr", "not perpendicular", "63.4", "Resample"});
    writeBytes(dir / "shear.mhd", metaHeader("scan.raw", "TransformMatrix = 1 0 0 0.5 1 0 0 0 1\n"));
    expectError([&] { loadVolume(dir / "shear.mhd"); }, {"shear.mhd", "not perpendicular", "Resample"});
    auto sheared = niftiBytes();
    sheared = with(sheared, 280 + 4, 0.5f);  // srow_x[1]
    writeBytes(dir / "shear.nii", sheared);
    expectError([&] { loadVolume(dir / "shear.nii"); }, {"shear.nii", "not perpendicular", "Resample"});
    // A rotation (perpendicular axes, six decimals) is read.
    writeBytes(dir / "turned.nhdr", nrrd + "space directions: (0.866025,0.5,0) (-0.5,0.866025,0) (0,0,1)\n"
                                           "data file: scan.raw\n");
    EXPECT_NEAR(loadVolume(dir / "turned.nhdr").direction[3], 0.5, 1e-6);
    fs::remove_all(dir);
}

TEST(HostileHeaders, NiftiHeaderLiesAreRefused) {
    const auto dir = scratchDir("niftilies");
    const std::string good = niftiBytes();
    writeBytes(dir / "good.nii", good);
    ASSERT_EQ(loadVolume(dir / "good.nii").dims(), openvdb::Coord(10, 9, 8));
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const std::vector<std::tuple<std::string, std::string, std::vector<std::string>>> cases = {
        // float voxels read as int16: noise meshed
        {"bitpix.nii", with(good, 72, std::int16_t(32)), {"datatype (4, 16 bits per voxel) and bitpix (32) disagree"}},
        // header bytes became voxels (nifti1_io moves the offset to 352 silently)
        {"voxneg.nii", with(good, 108, -4.0f), {"vox_offset", "negative"}},
        {"voxzero.nii", with(good, 108, 0.0f), {"vox_offset", "is 0, inside the 352-byte header"}},
        {"voxnan.nii", with(good, 108, nan), {"vox_offset", "nan"}},
        {"voxin.nii", with(good, 108, 100.0f), {"vox_offset", "is 100, inside"}},
        // 1 mm assumed silently
        {"pixdim0.nii", with(with(good, 254, std::int16_t(0)), 84, 0.0f), {"pixdim[2]", "is 0", "no sform"}},
        // a scrambled sub-volume meshed
        {"dimsmall.nii", with(good, 46, std::int16_t(4)), {"bytes more voxel data", "dim too small"}},
        // was "every voxel has the value 0"
        {"cut348.nii", good.substr(0, 348), {"truncated", "1792", "348"}},
    };
    for (const auto& [name, bytes, pieces] : cases) {
        SCOPED_TRACE(name);
        writeBytes(dir / name, bytes);
        std::vector<std::string> want = pieces;
        want.push_back(name);
        const std::string msg = expectError([&] { loadVolume(dir / name); }, want);
        EXPECT_NE(msg.find("export"), std::string::npos) << msg;
    }
    fs::remove_all(dir);
}

TEST(HostileHeaders, AnalyzePairsBlameTheirImgAndRefuseItShort) {
    // An Analyze .hdr whose .img was cut to 1,000 bytes was meshed (zeros
    // after the cut); a missing .img was blamed on the .hdr.
    const auto dir = scratchDir("analyze");
    std::string header = niftiBytes().substr(0, 348);
    std::memcpy(header.data() + 344, "\0\0\0\0", 4);  // Analyze 7.5: no NIfTI magic
    header = with(with(header, 108, 0.0f), 254, std::int16_t(0));
    const std::string img = niftiBytes().substr(352);
    writeBytes(dir / "scan.hdr", header);
    writeBytes(dir / "scan.img", img);
    const auto control = loadVolume(dir / "scan.hdr");
    EXPECT_EQ(control.dims(), openvdb::Coord(10, 9, 8));
    EXPECT_EQ(control.maxValue, 196);
    writeBytes(dir / "scan.img", img.substr(0, 1000));
    expectError([&] { loadVolume(dir / "scan.hdr"); }, {"scan.img", "truncated", "1440", "1000"});
    fs::remove(dir / "scan.img");
    const std::string msg = expectError([&] { loadVolume(dir / "scan.hdr"); }, {"'scan.img' is missing"});
    EXPECT_EQ(msg.find("header cannot be read"), std::string::npos) << msg;
    // A gzipped .img beside the .hdr is ITK's to read, as before.
    gzFile gz = gzopen((dir / "scan.img.gz").c_str(), "wb");
    ASSERT_NE(gz, nullptr);
    gzwrite(gz, img.data(), static_cast<unsigned>(img.size()));
    gzclose(gz);
    EXPECT_EQ(loadVolume(dir / "scan.hdr").maxValue, 196);
    fs::remove_all(dir);
}

TEST(HostileHeaders, NiftiTwoIsReadLikeTheSameImageInNiftiOne) {
    // A valid NIfTI-2 file was called damaged (ITK 5.2 reads NIfTI-1 only).
    // The control: the same voxels and geometry as NIfTI-1, read by ITK.
    const auto dir = scratchDir("nifti2");
    std::string one = niftiBytes();
    const float spacing[3] = {0.8f, 0.9f, 1.25f}, origin[3] = {10.5f, -3.0f, 7.25f};
    for (int a = 0; a < 3; ++a) {
        one = with(one, 80 + 4 * a, spacing[a]);
        one = with(one, 280 + 16 * a + 4 * a, spacing[a]);
        one = with(one, 280 + 16 * a + 12, origin[a]);
    }
    writeBytes(dir / "one.nii", one);
    // The same header in NIfTI-2's layout (540 bytes, 64-bit fields).
    std::string two(544, '\0');
    auto put = [&](int at, auto v) { std::memcpy(two.data() + at, &v, sizeof v); };
    put(0, std::int32_t(540));
    std::memcpy(two.data() + 4, "n+2\0\r\n\032\n", 8);
    put(12, std::int16_t(4));
    put(14, std::int16_t(16));
    const std::int64_t dim[8] = {3, 10, 9, 8, 1, 1, 1, 1};
    std::memcpy(two.data() + 16, dim, sizeof dim);
    put(104, 1.0);
    for (int a = 0; a < 3; ++a) put(112 + 8 * a, double(spacing[a]));
    put(168, std::int64_t(544));
    put(176, 1.0);  // scl_slope
    put(348, std::int32_t(1));  // sform_code
    for (int a = 0; a < 3; ++a) {
        put(400 + 32 * a + 8 * a, double(spacing[a]));
        put(400 + 32 * a + 24, double(origin[a]));
    }
    two += one.substr(352);
    writeBytes(dir / "two.nii", two);
    const Volume a = loadVolume(dir / "one.nii"), b = loadVolume(dir / "two.nii");
    EXPECT_EQ(b.format, "NIfTI");
    EXPECT_EQ(b.pixelType, "int16");
    ASSERT_EQ(a.dims(), b.dims());
    for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(a.origin[k], b.origin[k], 1e-6) << k;
        EXPECT_NEAR(a.spacing[k], b.spacing[k], 1e-6) << k;
    }
    for (int k = 0; k < 9; ++k) EXPECT_NEAR(a.direction[k], b.direction[k], 1e-9) << k;
    EXPECT_EQ(a.minValue, b.minValue);
    EXPECT_EQ(a.maxValue, b.maxValue);
    auto ra = a.intensity->getConstAccessor();
    auto rb = b.intensity->getConstAccessor();
    for (int z = 0; z < 8; ++z)
        for (int y = 0; y < 9; ++y)
            for (int x = 0; x < 10; ++x)
                ASSERT_EQ(ra.getValue({x, y, z}), rb.getValue({x, y, z})) << x << "," << y << "," << z;
    // NIfTI-2's own header lies are refused as NIfTI-1's.
    writeBytes(dir / "two-short.nii", two.substr(0, two.size() - 10));
    expectError([&] { loadVolume(dir / "two-short.nii"); }, {"two-short.nii", "truncated"});
    fs::remove_all(dir);
}

TEST(HostileHeaders, APipeOrDeviceAsTheInputIsRefusedWithoutBlocking) {
    // A named pipe blocked the reader for ever.
    const auto dir = scratchDir("fifo");
    ASSERT_EQ(mkfifo((dir / "scan.nii").c_str(), 0600), 0);
    expectError([&] { loadVolume(dir / "scan.nii"); }, {"scan.nii", "a named pipe", "Save the scan to a file"});
    expectError([&] { loadVolume("/dev/zero"); }, {"/dev/zero", "a device"});
    fs::remove_all(dir);
}

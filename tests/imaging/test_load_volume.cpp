// loadVolume: formats, geometry (origin, spacing, direction), labels, real scans.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <openvdb/io/File.h>

#include "TestSupport.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/imaging/Volume.hpp"

using namespace isohex::imaging;
using namespace isohex::imaging::test;

namespace {

// A smooth blob with a gradient, anisotropic spacing and a non-zero origin.
const Dims kDims{20, 18, 12};
Geometry blobGeometry() {
    Geometry g;
    g.origin = {-10.5, 20.25, 3.0};
    g.spacing = {0.5, 0.75, 1.25};
    return g;
}
std::vector<std::int16_t> blobValues() {
    std::vector<std::int16_t> v;
    for (int z = 0; z < kDims[2]; ++z)
        for (int y = 0; y < kDims[1]; ++y)
            for (int x = 0; x < kDims[0]; ++x) {
                const double r2 = (x - 9.5) * (x - 9.5) + (y - 8.0) * (y - 8.0) + 2 * (z - 6.0) * (z - 6.0);
                v.push_back(static_cast<std::int16_t>(1000 - 10 * r2 + x));
            }
    return v;
}

openvdb::Vec3d world(const Volume& v, int i, int j, int k) {
    return v.transform().indexToWorld(openvdb::Vec3d(i, j, k));
}

void expectSameGrid(const Volume& a, const Volume& b) {
    ASSERT_EQ(a.box, b.box);
    ASSERT_EQ(a.kind, VolumeKind::Intensity);
    ASSERT_EQ(b.kind, VolumeKind::Intensity);
    auto ca = a.intensity->getConstAccessor();
    auto cb = b.intensity->getConstAccessor();
    std::int64_t differ = 0;
    for (auto c = a.box.begin(); c; ++c) differ += ca.getValue(*c) != cb.getValue(*c);
    EXPECT_EQ(differ, 0) << a.format << " vs " << b.format;
    EXPECT_EQ(a.intensity->activeVoxelCount(), b.intensity->activeVoxelCount());
    for (auto corner : {openvdb::Coord(0, 0, 0), a.box.max(), openvdb::Coord(3, 7, 5)}) {
        const auto wa = world(a, corner.x(), corner.y(), corner.z());
        const auto wb = world(b, corner.x(), corner.y(), corner.z());
        for (int d = 0; d < 3; ++d) EXPECT_NEAR(wa[d], wb[d], 1e-6) << a.format << " vs " << b.format;
    }
}

}  // namespace

TEST(LoadVolume, SameVolumeInNiftiNrrdMetaImageAndDicomGivesIdenticalGridsAndTransforms) {
    const auto dir = scratchDir("formats");
    const auto g = blobGeometry();
    const auto v = blobValues();
    writeImage(dir / "blob.nii.gz", kDims, v, g);
    writeImage(dir / "blob.nii", kDims, v, g);
    writeImage(dir / "blob.nrrd", kDims, v, g);
    writeImage(dir / "blob.mha", kDims, v, g);
    writeImage(dir / "blob.mhd", kDims, v, g);
    writeDicomSeries(dir / "dicom", kDims, v, g, "1.2.826.0.1.3680043.2.1125.99.7");

    const Volume ref = loadVolume(dir / "blob.nii.gz");
    EXPECT_EQ(ref.format, "NIfTI");
    EXPECT_EQ(ref.pixelType, "int16");
    EXPECT_EQ(ref.dims(), openvdb::Coord(kDims[0], kDims[1], kDims[2]));
    for (const char* name : {"blob.nii", "blob.nrrd", "blob.mha", "blob.mhd", "dicom"}) {
        SCOPED_TRACE(name);
        expectSameGrid(ref, loadVolume(dir / name));
    }
    const Volume dicom = loadVolume(dir / "dicom");
    EXPECT_EQ(dicom.format, "DICOM");
    EXPECT_EQ(dicom.seriesUid, "1.2.826.0.1.3680043.2.1125.99.7");
    fs::remove_all(dir);
}

TEST(LoadVolume, AFolderHoldingOneMultiFrameDicomIsReadAsItsVolume) {
    // A folder with one multi-frame DICOM file (enhanced CT or MR; ITK writes
    // a 3-D image so) was refused as "a single slice".
    const auto dir = scratchDir("multiframe");
    const auto g = blobGeometry();
    const auto v = blobValues();
    writeImage(dir / "blob.nii.gz", kDims, v, g);
    fs::create_directories(dir / "dicom");
    writeMultiFrameDicom(dir / "dicom" / "volume.dcm", kDims, v, g);
    const Volume ref = loadVolume(dir / "blob.nii.gz");
    const Volume folder = loadVolume(dir / "dicom");
    EXPECT_EQ(folder.format, "DICOM");
    EXPECT_EQ(folder.dims(), openvdb::Coord(kDims[0], kDims[1], kDims[2]));
    expectSameGrid(ref, folder);
    expectSameGrid(ref, loadVolume(dir / "dicom" / "volume.dcm"));  // the file itself, as before
    fs::remove_all(dir);
}

TEST(LoadVolume, VoxelCentresMapToItkPhysicalPoints) {
    const auto dir = scratchDir("geometry");
    const auto g = blobGeometry();
    writeImage(dir / "blob.nrrd", kDims, blobValues(), g);
    const Volume vol = loadVolume(dir / "blob.nrrd");
    for (auto idx : {std::array<long, 3>{0, 0, 0}, {19, 17, 11}, {4, 9, 2}}) {
        const auto p = itkPhysicalPoint(g, idx);
        const auto w = world(vol, int(idx[0]), int(idx[1]), int(idx[2]));
        for (int d = 0; d < 3; ++d) EXPECT_NEAR(w[d], p[d], 1e-9);
    }
    // The grid holds the scan exactly and keeps the whole scanned box active.
    EXPECT_EQ(vol.intensity->activeVoxelCount(), vol.box.volume());
    EXPECT_EQ(vol.intensity->tree().getValue(openvdb::Coord(4, 9, 2)), blobValues()[4 + 20 * (9 + 18 * 2)]);
    EXPECT_FLOAT_EQ(vol.intensity->background(), float(vol.minValue));
    fs::remove_all(dir);
}

TEST(LoadVolume, RotatedDirectionMatrixIsHonoured) {
    const auto dir = scratchDir("rotated");
    Geometry g = blobGeometry();
    // A rotation by 30 degrees about (1,2,2)/3, so no axis stays put.
    const double c = std::cos(M_PI / 6), s = std::sin(M_PI / 6), u[3] = {1 / 3.0, 2 / 3.0, 2 / 3.0};
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) {
            const double cross[3][3] = {{0, -u[2], u[1]}, {u[2], 0, -u[0]}, {-u[1], u[0], 0}};
            g.direction[3 * r + k] = (r == k ? c : 0.0) + s * cross[r][k] + (1 - c) * u[r] * u[k];
        }
    for (const char* name : {"rot.mha", "rot.nrrd", "rot.nii.gz"}) {
        SCOPED_TRACE(name);
        writeImage(dir / name, kDims, blobValues(), g);
        const Volume vol = loadVolume(dir / name);
        std::mt19937 rng(7);
        for (int n = 0; n < 50; ++n) {
            const std::array<long, 3> idx{long(rng() % kDims[0]), long(rng() % kDims[1]), long(rng() % kDims[2])};
            const auto fromFile = itkPhysicalPoint(dir / name, idx);
            const auto w = world(vol, int(idx[0]), int(idx[1]), int(idx[2]));
            for (int d = 0; d < 3; ++d) EXPECT_NEAR(w[d], fromFile[d], 1e-9);
            const auto intended = itkPhysicalPoint(g, idx);  // before the file's rounding
            for (int d = 0; d < 3; ++d) EXPECT_NEAR(w[d], intended[d], 1e-4);
        }
        for (int k = 0; k < 9; ++k) EXPECT_NEAR(vol.direction[k], g.direction[k], 1e-5);
    }
    fs::remove_all(dir);
}

TEST(LoadVolume, DicomRescaleSlopeAndInterceptAreApplied) {
    const auto dir = scratchDir("rescale");
    const auto v = blobValues();
    writeDicomSeries(dir, kDims, v, blobGeometry(), "1.2.826.0.1.3680043.2.1125.99.8", 2.0, -1024.0);
    // ITK (since 4.7) stores (value - intercept) / slope with the tags set, so
    // the files hold rescaled pixels and only a reader that applies the
    // slope and intercept gets the original values back.
    EXPECT_EQ(std::stod(dicomTag(dir / "slice0.dcm", "0028|1053")), 2.0);
    EXPECT_EQ(std::stod(dicomTag(dir / "slice0.dcm", "0028|1052")), -1024.0);
    const Volume vol = loadVolume(dir);
    auto acc = vol.intensity->getConstAccessor();
    int off = 0;
    for (auto c = vol.box.begin(); c; ++c) {
        const std::size_t i = (*c).x() + 20 * ((*c).y() + 18 * (*c).z());
        off += std::fabs(acc.getValue(*c) - v[i]) > 1.0f;  // odd values round by one
    }
    EXPECT_EQ(off, 0);
    fs::remove_all(dir);
}

TEST(LoadVolume, DicomFolderDefaultsToTheSeriesWithMostSlicesAndHonoursTheUidOption) {
    const auto dir = scratchDir("two_series");
    const auto v = blobValues();
    const std::string big = "1.2.826.0.1.3680043.2.1125.99.21", small = "1.2.826.0.1.3680043.2.1125.99.22";
    writeDicomSeries(dir, kDims, v, blobGeometry(), big, 1, 0, "big");
    const Dims few{kDims[0], kDims[1], 5};
    writeDicomSeries(dir, few, std::vector<std::int16_t>(v.begin(), v.begin() + 20 * 18 * 5),
                     blobGeometry(), small, 1, 0, "small");
    EXPECT_EQ(loadVolume(dir).dims().z(), 12);
    LoadOptions o;
    o.seriesUid = small;
    const Volume chosen = loadVolume(dir, o);
    EXPECT_EQ(chosen.dims().z(), 5);
    EXPECT_EQ(chosen.seriesUid, small);
    fs::remove_all(dir);
}

TEST(LoadVolume, IntegerImageIsALabelMapOnlyWhenAsked) {
    const auto dir = scratchDir("labels");
    std::vector<std::uint8_t> labels(std::size_t(kDims[0]) * kDims[1] * kDims[2], 0);
    for (std::size_t i = 0; i < labels.size(); ++i) labels[i] = std::uint8_t(i % 7 == 0 ? 3 : (i % 5 == 0 ? 9 : 0));
    writeImage(dir / "labels.nii.gz", kDims, labels, blobGeometry());
    EXPECT_EQ(loadVolume(dir / "labels.nii.gz").kind, VolumeKind::Intensity);
    LoadOptions o;
    o.labels = true;
    const Volume vol = loadVolume(dir / "labels.nii.gz", o);
    ASSERT_EQ(vol.kind, VolumeKind::Labels);
    EXPECT_EQ(vol.labels->background(), 0);
    EXPECT_EQ(vol.labels->tree().getValue(openvdb::Coord(0, 0, 0)), 3);
    EXPECT_EQ(vol.labels->tree().getValue(openvdb::Coord(5, 0, 0)), 9);
    EXPECT_EQ(vol.maxValue, 9);
    fs::remove_all(dir);
}

TEST(LoadVolume, FolderOfExrSlicesUsesTheCallersSpacing) {
    const auto dir = scratchDir("exr");
    const int w = 9, h = 7, slices = 11;  // 11 slices: natural order must put 10 after 9
    for (int z = 0; z < slices; ++z) {
        std::vector<float> s(w * h);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) s[x + w * y] = float(100 * z + 10 * y + x);
        writeExrSlice(dir / ("slice" + std::to_string(z) + ".exr"), w, h, s);
    }
    LoadOptions o;
    o.sliceSpacing = {0.02, 0.02, 0.05};
    o.sliceOrigin = {1, 2, 3};
    const Volume vol = loadVolume(dir, o);
    EXPECT_EQ(vol.format, "OpenEXR");
    EXPECT_EQ(vol.dims(), openvdb::Coord(w, h, slices));
    EXPECT_EQ(vol.intensity->tree().getValue(openvdb::Coord(4, 5, 10)), 1054.0f);
    const auto p = world(vol, 4, 5, 10);
    EXPECT_NEAR(p[0], 1.08, 1e-12);
    EXPECT_NEAR(p[1], 2.10, 1e-12);
    EXPECT_NEAR(p[2], 3.50, 1e-12);
    fs::remove_all(dir);
}

TEST(LoadVolume, VdbFileRoundTripsGridAndTransform) {
    const auto dir = scratchDir("vdb");
    writeImage(dir / "blob.nrrd", kDims, blobValues(), blobGeometry());
    const Volume a = loadVolume(dir / "blob.nrrd");
    {
        openvdb::io::File f((dir / "blob.vdb").string());
        f.write({a.intensity});
    }
    const Volume b = loadVolume(dir / "blob.vdb");
    EXPECT_EQ(b.format, "OpenVDB");
    expectSameGrid(a, b);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(b.spacing[k], a.spacing[k], 1e-12);
    // Cut short, with metadata and two grids in it: a clear error before
    // OpenVDB reads it (it allocated gigabytes for the garbage lengths).
    {
        openvdb::FloatGrid::Ptr second = a.intensity->deepCopy();
        second->setName("second");
        openvdb::MetaMap meta;
        meta.insertMeta("creator", openvdb::StringMetadata("isohex test"));
        openvdb::io::File f((dir / "two.vdb").string());
        f.write({a.intensity, second}, meta);
    }
    EXPECT_NO_THROW(loadVolume(dir / "two.vdb"));  // whole, the walk accepts it
    const auto whole = fs::file_size(dir / "two.vdb");
    for (const double keep : {0.9, 0.6, 0.2}) {
        SCOPED_TRACE(keep);
        fs::copy_file(dir / "two.vdb", dir / "cut.vdb", fs::copy_options::overwrite_existing);
        fs::resize_file(dir / "cut.vdb", static_cast<std::uintmax_t>(keep * double(whole)));
        try {
            loadVolume(dir / "cut.vdb");
            ADD_FAILURE() << "no error";
        } catch (const isohex::Error& e) {
            EXPECT_NE(std::string(e.what()).find("cut.vdb: the OpenVDB file is damaged or truncated"), std::string::npos)
                << e.what();
        }
    }
    fs::remove_all(dir);
}

TEST(LoadVolume, RealSkullCtKeepsItsAnisotropicVoxels) {
    const Volume vol = loadVolume(sharedData() / "skull_ct.nii.gz");
    EXPECT_EQ(vol.dims(), openvdb::Coord(64, 64, 64));
    EXPECT_NEAR(vol.spacing[0], 3.943, 1e-3);
    EXPECT_NEAR(vol.spacing[2], 3.651, 1e-3);
    const auto step = world(vol, 0, 0, 1) - world(vol, 0, 0, 0);
    EXPECT_NEAR(step.length(), 3.651, 1e-3);
    EXPECT_EQ(vol.pixelType, "float32");
    EXPECT_LT(vol.minValue, 2.9);
    EXPECT_GT(vol.maxValue, 2.9);
}

TEST(LoadVolume, RealBrainMriKeepsItsNonZeroOrigin) {
    const auto path = sharedData() / "ch2bet.nii.gz";
    const Volume vol = loadVolume(path);
    EXPECT_EQ(vol.dims(), openvdb::Coord(181, 217, 181));
    EXPECT_EQ(vol.pixelType, "uint8");
    const double originNorm = std::sqrt(vol.origin[0] * vol.origin[0] + vol.origin[1] * vol.origin[1] +
                                        vol.origin[2] * vol.origin[2]);
    EXPECT_GT(originNorm, 10.0);
    for (auto idx : {std::array<long, 3>{0, 0, 0}, {90, 108, 90}, {180, 216, 180}}) {
        const auto p = itkPhysicalPoint(path, idx);
        const auto w = world(vol, int(idx[0]), int(idx[1]), int(idx[2]));
        for (int d = 0; d < 3; ++d) EXPECT_NEAR(w[d], p[d], 1e-9);
    }
}

TEST(LoadVolume, RealLabelAtlasLoadsAsLabels) {
    LoadOptions o;
    o.labels = true;
    const Volume vol = loadVolume(sharedData() / "JHU-WhiteMatter-labels-2mm.nii.gz", o);
    ASSERT_EQ(vol.kind, VolumeKind::Labels);
    EXPECT_EQ(vol.dims(), openvdb::Coord(91, 109, 91));
    EXPECT_EQ(vol.minValue, 0);
    EXPECT_EQ(vol.maxValue, 48);
    EXPECT_NEAR(vol.spacing[1], 2.0, 1e-9);
}

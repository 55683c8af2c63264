// NIfTI-1 files read with libnifti2 (imaging/src/NiftiRead.cpp) against ITK's
// reader (ItkImageFile.cpp, in the ITK plugin), which read them before: for
// every NIfTI-1 file at hand (the shared real scans, samples/make_phantoms.py's
// phantoms, and headers written here for each of ITK's geometry rules, value
// scalings, types and dimensions) both give the same RawVolume: values bit
// for bit (NaN included), pixel type, sizes, and spacing, origin and
// direction exactly. The files libnifti2 must leave to ITK (readWithNiftiLib
// returns nothing) are the ones expected, and where ITK refuses a file,
// loadVolume's error is ITK's path's word for word.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <optional>

#include <zlib.h>

#include "../../imaging/src/RawVolume.hpp"
#include "../../imaging/src/ReaderPlugins.hpp"
#include "TestSupport.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/imaging/Volume.hpp"

using namespace isohex::imaging;
using namespace isohex::imaging::test;
using isohex::imaging::detail::RawVolume;

namespace {

// A NIfTI-1 header and its voxels, written as .nii or .nii.gz, little or
// big endian. Defaults: 7x6x5 float32 voxels, 1 mm, no qform or sform.
struct Nifti1 {
    std::int16_t dim[8] = {3, 7, 6, 5, 1, 1, 1, 1};
    std::int16_t datatype = 16;  // float32
    float pixdim[8] = {1, 1, 1, 1, 1, 1, 1, 1};
    float slope = 0, inter = 0;
    unsigned char xyztUnits = 2;  // mm
    std::int16_t intent = 0;
    std::int16_t qcode = 0, scode = 0;
    float quatern[6] = {0, 0, 0, 0, 0, 0};  // b c d, offsets x y z
    float srow[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    char magic[4] = {'n', '+', '1', '\0'};
    bool bigEndian = false;
    // Voxel values as doubles, converted to the datatype; empty: a pattern
    // of positive and negative values of many magnitudes.
    std::vector<double> values;

    std::int64_t voxels() const {
        std::int64_t n = 1;
        for (int d = 1; d <= dim[0]; ++d) n *= dim[d];
        return n;
    }
    int bytesPerVoxel() const {
        switch (datatype) {
            case 2: case 256: return 1;
            case 4: case 512: return 2;
            case 8: case 16: case 768: return 4;
            default: return 8;  // 64 float64, 1024 int64, 1280 uint64, 32 complex64
        }
    }
    double value(std::int64_t i) const {
        if (!values.empty()) return values[static_cast<std::size_t>(i)];
        const bool isSigned = datatype != 2 && datatype != 512 && datatype != 768 && datatype != 1280;
        const double v = double((i * 37) % 101) + 0.25 * double(i % 4);
        return isSigned && i % 3 == 0 ? -v : v;
    }

    std::string bytes() const {
        std::string h(352, '\0');
        auto put = [&](int at, auto v) {
            unsigned char b[sizeof v];
            std::memcpy(b, &v, sizeof v);
            if (bigEndian) std::reverse(b, b + sizeof v);
            std::memcpy(h.data() + at, b, sizeof v);
        };
        put(0, std::int32_t(348));
        for (int k = 0; k < 8; ++k) put(40 + 2 * k, dim[k]);
        put(68, intent);
        put(70, datatype);
        put(72, std::int16_t(datatype == 32 ? 64 : 8 * bytesPerVoxel()));
        for (int k = 0; k < 8; ++k) put(76 + 4 * k, pixdim[k]);
        put(108, 352.0f);
        put(112, slope);
        put(116, inter);
        h[123] = static_cast<char>(xyztUnits);
        put(252, qcode);
        put(254, scode);
        for (int k = 0; k < 6; ++k) put(256 + 4 * k, quatern[k]);
        for (int k = 0; k < 12; ++k) put(280 + 4 * k, srow[k]);
        std::memcpy(h.data() + 344, magic, 4);
        std::string data;
        const int width = bytesPerVoxel();
        for (std::int64_t i = 0; i < voxels(); ++i) {
            unsigned char b[8];
            const double v = value(i);
            switch (datatype) {
                case 2: { auto x = static_cast<std::uint8_t>(v); std::memcpy(b, &x, 1); break; }
                case 256: { auto x = static_cast<std::int8_t>(v); std::memcpy(b, &x, 1); break; }
                case 4: { auto x = static_cast<std::int16_t>(v); std::memcpy(b, &x, 2); break; }
                case 512: { auto x = static_cast<std::uint16_t>(v); std::memcpy(b, &x, 2); break; }
                case 8: { auto x = static_cast<std::int32_t>(v); std::memcpy(b, &x, 4); break; }
                case 768: { auto x = static_cast<std::uint32_t>(v); std::memcpy(b, &x, 4); break; }
                case 16: { auto x = static_cast<float>(v); std::memcpy(b, &x, 4); break; }
                case 1024: { auto x = static_cast<std::int64_t>(v); std::memcpy(b, &x, 8); break; }
                case 1280: { auto x = static_cast<std::uint64_t>(v); std::memcpy(b, &x, 8); break; }
                default: { std::memcpy(b, &v, 8); break; }  // float64; complex64 as two floats' bytes
            }
            if (bigEndian) std::reverse(b, b + width);
            data.append(reinterpret_cast<const char*>(b), static_cast<std::size_t>(width));
        }
        return h + data;
    }

    fs::path write(const fs::path& path) const {
        const std::string b = bytes();
        if (path.extension() == ".gz") {
            gzFile gz = gzopen(path.c_str(), "wb");
            gzwrite(gz, b.data(), static_cast<unsigned>(b.size()));
            gzclose(gz);
        } else {
            writeBytes(path, b);
        }
        return path;
    }
};

// The quaternion's rotation times the spacings (nifti's formula, in double),
// as float srow rows with these offsets: the header's sform equal to its
// qform up to float rounding.
void sformFromQuaternion(Nifti1& h) {
    double b = h.quatern[0], c = h.quatern[1], d = h.quatern[2];
    const double a = std::sqrt(1.0 - (b * b + c * c + d * d));
    const double zd = h.pixdim[0] < 0 ? -h.pixdim[3] : h.pixdim[3];
    const double r[3][3] = {{(a * a + b * b - c * c - d * d) * h.pixdim[1], 2 * (b * c - a * d) * h.pixdim[2], 2 * (b * d + a * c) * zd},
                            {2 * (b * c + a * d) * h.pixdim[1], (a * a + c * c - b * b - d * d) * h.pixdim[2], 2 * (c * d - a * b) * zd},
                            {2 * (b * d - a * c) * h.pixdim[1], 2 * (c * d + a * b) * h.pixdim[2], (a * a + d * d - c * c - b * b) * zd}};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) h.srow[4 * i + j] = static_cast<float>(r[i][j]);
        h.srow[4 * i + 3] = h.quatern[3 + i];
    }
}

// An oblique qform: about 40 degrees about (1, -2, 3), left-handed, 0.9 x 1.1 x 1.3 mm.
Nifti1 obliqueQform() {
    Nifti1 h;
    h.qcode = 1;
    h.pixdim[0] = -1;
    h.pixdim[1] = 0.9f;
    h.pixdim[2] = 1.1f;
    h.pixdim[3] = 1.3f;
    const float quatern[6] = {0.0914f, -0.1828f, 0.2742f, 10.5f, -20.25f, 30.0f};
    std::memcpy(h.quatern, quatern, sizeof quatern);
    return h;
}

// An axis-aligned sform of the header's pixdim with these offsets.
void alignedSform(Nifti1& h, std::int16_t code, float x, float y, float z) {
    h.scode = code;
    const float srow[12] = {h.pixdim[1], 0, 0, x, 0, h.pixdim[2], 0, y, 0, 0, h.pixdim[3], z};
    std::memcpy(h.srow, srow, sizeof srow);
}

void expectSameVolume(const RawVolume& fast, const RawVolume& itk) {
    EXPECT_EQ(fast.format, itk.format);
    EXPECT_EQ(fast.pixelType, itk.pixelType);
    EXPECT_EQ(fast.dims, itk.dims);
    EXPECT_EQ(fast.start, itk.start);
    EXPECT_EQ(fast.fileDims, itk.fileDims);
    EXPECT_EQ(fast.streamed, itk.streamed);
    ASSERT_EQ(fast.values.size(), itk.values.size());
    std::size_t differ = 0, first = 0;
    for (std::size_t i = 0; i < fast.values.size(); ++i)
        if (std::memcmp(&fast.values[i], &itk.values[i], sizeof(float)) != 0 && differ++ == 0) first = i;
    EXPECT_EQ(differ, 0u) << "first at " << first << ": " << fast.values[first] << " vs " << itk.values[first];
    EXPECT_EQ(fast.labels, itk.labels);
    for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(fast.origin[a], itk.origin[a]) << "origin " << a;
        EXPECT_EQ(fast.spacing[a], itk.spacing[a]) << "spacing " << a;
    }
    for (int k = 0; k < 9; ++k) EXPECT_EQ(fast.direction[std::size_t(k)], itk.direction[std::size_t(k)]) << "direction " << k;
}

enum class Expect { Read, LeftToItk };

// Reads `path` through libnifti2 and through ITK: the same RawVolume when
// libnifti2 reads it; when it leaves the file to ITK, loadVolume gives ITK's
// volume or ITK's error.
void compareWithItk(const fs::path& path, Expect expect, const LoadOptions& options = {}) {
    SCOPED_TRACE(path.filename().string());
    ASSERT_TRUE(isohex::imaging::detail::readsWithNiftiLib(path));
    const std::optional<RawVolume> fast = isohex::imaging::detail::readWithNiftiLib(path, options);
    EXPECT_EQ(fast.has_value(), expect == Expect::Read) << (fast ? "read by libnifti2" : "left to ITK");
    std::optional<RawVolume> itk;
    std::string itkError;
    try {
        itk = isohex::imaging::detail::itkReaders().readImageFile(path, options);
    } catch (const isohex::Error& e) {
        itkError = e.what();
    }
    if (fast) {
        ASSERT_TRUE(itk) << "ITK refuses what libnifti2 read: " << itkError;
        expectSameVolume(*fast, *itk);
    }
    if (!itk) {
        std::string loadError;
        try {
            loadVolume(path, options);
        } catch (const isohex::Error& e) {
            loadError = e.what();
        }
        EXPECT_EQ(loadError, itkError);
    }
}

LoadOptions labels() {
    LoadOptions o;
    o.labels = true;
    return o;
}

LoadOptions volume(int index) {
    LoadOptions o;
    o.volumeIndex = index;
    return o;
}

}  // namespace

TEST(NiftiLibRead, SharedScansAreReadAsItkReadsThem) {
    compareWithItk(sharedData() / "skull_ct.nii.gz", Expect::Read);
    compareWithItk(sharedData() / "JHU-WhiteMatter-labels-2mm.nii.gz", Expect::Read);
    compareWithItk(sharedData() / "JHU-WhiteMatter-labels-2mm.nii.gz", Expect::Read, labels());
    // An sform only, with an offset: ITK takes it if its float SVD finds it
    // affine (see NiftiRead.cpp itkIsAffine), else refuses the file.
    compareWithItk(sharedData() / "ch2bet.nii.gz", Expect::LeftToItk);
}

TEST(NiftiLibRead, PhantomsAreReadAsItkReadsThem) {
    const auto dir = scratchDir("nifti_phantoms");
    const fs::path script = fs::path(ISOHEX_SOURCE_DIR) / "samples" / "make_phantoms.py";
    const std::string command = "/usr/bin/python3 '" + script.string() + "' '" + dir.string() + "' > /dev/null";
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
    for (const char* name : {"sphere", "torus", "thin_plate", "two_spheres", "two_materials"})
        compareWithItk(dir / (std::string(name) + ".nii.gz"), Expect::Read);
    compareWithItk(dir / "two_materials.nii.gz", Expect::Read, labels());
}

// ITK 5.2's choice between the sform and the qform (itkNiftiImageIO.cxx,
// SetImageIOOrientationFromNIfTI), case by case.
TEST(NiftiLibRead, GeometryIsItksChoiceOfSformOrQform) {
    const auto dir = scratchDir("nifti_geometry");
    {  // no codes: origin 0, identity, spacing from pixdim; a negative one turns its axis
        Nifti1 h;
        h.pixdim[1] = 0.8f;
        h.pixdim[2] = -1.2f;
        h.pixdim[3] = 2.5f;
        compareWithItk(h.write(dir / "no_codes.nii"), Expect::Read);
    }
    // qform only, oblique and left-handed; and a 180 degree rotation (nifti's special case)
    compareWithItk(obliqueQform().write(dir / "qform_only.nii.gz"), Expect::Read);
    {
        Nifti1 h = obliqueQform();
        const float quatern[3] = {0.0f, 0.6f, 0.8f};
        std::memcpy(h.quatern, quatern, sizeof quatern);
        compareWithItk(h.write(dir / "qform_180.nii"), Expect::Read);
    }
    {  // a qform whose element (0,1), ITK's long double rounded to float once, is
       // not libnifti2's double rounded to float (found by search)
        Nifti1 h = obliqueQform();
        const float quatern[3] = {0.229061782f, -0.363904327f, 0.307871819f};
        std::memcpy(h.quatern, quatern, sizeof quatern);
        h.pixdim[2] = 1.08121181f;
        compareWithItk(h.write(dir / "qform_rounding.nii"), Expect::Read);
    }
    {  // sform only, equal to the pixdim grid: ITK's "similar" qform and sform
        Nifti1 h;
        h.pixdim[1] = 3.943f;
        h.pixdim[3] = 3.65f;
        alignedSform(h, 2, 0, 0, 0);
        compareWithItk(h.write(dir / "sform_only_at_zero.nii"), Expect::Read);
    }
    {  // sform only, offset: hangs on IsAffine (sform or a refusal), left to ITK
        Nifti1 h;
        alignedSform(h, 4, -90, -125, -71);
        compareWithItk(h.write(dir / "sform_only_offset.nii"), Expect::LeftToItk);
    }
    {  // both, the same matrix (as the JHU atlas)
        Nifti1 h;
        h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = 2;
        h.qcode = 4;
        const float quatern[6] = {0, 0, 0, -90, -126, -72};
        std::memcpy(h.quatern, quatern, sizeof quatern);
        alignedSform(h, 4, -90, -126, -72);
        compareWithItk(h.write(dir / "both_same.nii"), Expect::Read);
    }
    {  // both, different, sform aligned (code 2): ITK takes the qform
        Nifti1 h = obliqueQform();
        alignedSform(h, 2, 5, 6, 7);
        compareWithItk(h.write(dir / "both_differ_aligned.nii"), Expect::Read);
    }
    {  // both, different, sform scanner-anatomical (code 1): hangs on IsAffine
        Nifti1 h = obliqueQform();
        alignedSform(h, 1, 5, 6, 7);
        compareWithItk(h.write(dir / "both_differ_scanner.nii"), Expect::LeftToItk);
    }
    {  // both, within 1e-5 of each other, scanner-anatomical: ITK takes the sform
        Nifti1 h = obliqueQform();
        sformFromQuaternion(h);
        h.scode = 1;
        h.srow[1] += 2e-6f;
        compareWithItk(h.write(dir / "both_similar_scanner.nii"), Expect::Read);
    }
    {  // both similar, sform aligned (code 2): the sform unless IsAffine says affine; left to ITK
        Nifti1 h = obliqueQform();
        sformFromQuaternion(h);
        h.scode = 2;
        h.srow[1] += 2e-6f;
        compareWithItk(h.write(dir / "both_similar_aligned.nii"), Expect::LeftToItk);
    }
    {  // a sheared sform and a qform: ITK takes the qform
        Nifti1 h = obliqueQform();
        alignedSform(h, 2, 5, 6, 7);
        h.srow[1] = 0.5f;
        compareWithItk(h.write(dir / "sheared_sform_with_qform.nii"), Expect::Read);
    }
    {  // an sform whose columns are not pixdim long, and a qform: the qform
        Nifti1 h = obliqueQform();
        alignedSform(h, 1, 5, 6, 7);
        h.srow[0] = 2.0f;
        compareWithItk(h.write(dir / "sform_not_pixdim.nii"), Expect::Read);
    }
    {  // a zero pixdim with an sform: nifti takes 1, and the qform is used
        Nifti1 h = obliqueQform();
        alignedSform(h, 2, 5, 6, 7);
        h.pixdim[2] = 0;
        compareWithItk(h.write(dir / "pixdim_zero.nii"), Expect::Read);
    }
    {  // a sheared sform alone: ITK refuses it
        Nifti1 h;
        alignedSform(h, 2, 5, 6, 7);
        h.srow[1] = 0.5f;
        compareWithItk(h.write(dir / "sheared_sform_only.nii"), Expect::LeftToItk);
    }
    for (unsigned char units : {1, 3}) {  // metres and microns scale the spacing, not the origin
        Nifti1 h = obliqueQform();
        h.xyztUnits = units;
        compareWithItk(h.write(dir / ("units_" + std::to_string(units) + ".nii")), Expect::Read);
    }
    {  // big-endian
        Nifti1 h = obliqueQform();
        h.bigEndian = true;
        h.datatype = 4;
        compareWithItk(h.write(dir / "big_endian.nii.gz"), Expect::Read);
    }
}

TEST(NiftiLibRead, ValuesTypesAndScalingAreItks) {
    const auto dir = scratchDir("nifti_values");
    for (std::int16_t type : {2, 256, 4, 512, 8, 768, 16, 64, 1024, 1280}) {
        Nifti1 h = obliqueQform();
        h.datatype = type;
        compareWithItk(h.write(dir / ("type_" + std::to_string(type) + ".nii")), Expect::Read);
        if (type == 2 || type == 4 || type == 8)
            compareWithItk(dir / ("type_" + std::to_string(type) + ".nii"), Expect::Read, labels());
    }
    // scl_slope 2, scl_inter 5: floats rescaled in their type, 32-bit
    // integers reported as float32
    for (std::int16_t type : {16, 64, 8, 768}) {
        Nifti1 h = obliqueQform();
        h.datatype = type;
        h.slope = 2;
        h.inter = 5;
        compareWithItk(h.write(dir / ("scaled_" + std::to_string(type) + ".nii")), Expect::Read);
        if (type == 8 || type == 768)  // integers read as float32 are labels still
            compareWithItk(dir / ("scaled_" + std::to_string(type) + ".nii"), Expect::Read, labels());
    }
    {  // a slope 0 is 1, the intercept still applies; an odd slope turns labels into reals
        Nifti1 h;
        h.slope = 0;
        h.inter = 5;
        compareWithItk(h.write(dir / "slope_zero.nii"), Expect::Read);
        Nifti1 odd;
        odd.datatype = 8;
        odd.slope = 0.1f;
        odd.inter = -3;
        compareWithItk(odd.write(dir / "slope_odd.nii.gz"), Expect::Read);
        compareWithItk(dir / "slope_odd.nii.gz", Expect::LeftToItk, labels());  // refused: not integers
    }
    // Integers of every width with a scaling (a CT's int16 with scl_inter
    // -1024): both readers give raw * slope + inter as float32. Their data on
    // disk is the integers' (its size was counted as floats, and every such
    // file but the 32-bit ones was refused as truncated or overlong).
    for (std::int16_t type : {2, 256, 4, 512, 1024, 1280}) {
        Nifti1 h;
        h.datatype = type;
        h.slope = type == 4 ? 1.0f : 2.0f;
        h.inter = type == 4 ? -1024.0f : 5.0f;
        const fs::path p = h.write(dir / ("scaled_int_" + std::to_string(type) + ".nii"));
        compareWithItk(p, Expect::Read);
        const std::optional<RawVolume> v = isohex::imaging::detail::readWithNiftiLib(p, {});
        ASSERT_TRUE(v);
        EXPECT_EQ(v->pixelType, "float32");
        ASSERT_EQ(v->values.size(), std::size_t(h.voxels()));
        for (std::int64_t i = 0; i < h.voxels(); ++i)
            ASSERT_EQ(v->values[std::size_t(i)], float(std::trunc(h.value(i))) * h.slope + h.inter) << type << " at " << i;
    }
    {  // NaN and infinities: NaN in the volume (ITK's reader zeroes them, isohex puts NaN back), 0 as labels
        Nifti1 h;
        h.values.assign(std::size_t(h.voxels()), 1.5);
        h.values[3] = std::numeric_limits<double>::quiet_NaN();
        h.values[40] = std::numeric_limits<double>::infinity();
        h.values[41] = -std::numeric_limits<double>::infinity();
        compareWithItk(h.write(dir / "non_finite.nii"), Expect::Read);
        h.datatype = 64;
        h.slope = 2;
        h.inter = 1;
        compareWithItk(h.write(dir / "non_finite_scaled.nii.gz"), Expect::Read);
        Nifti1 l;
        l.values.assign(std::size_t(l.voxels()), 2.0);
        l.values[5] = std::numeric_limits<double>::quiet_NaN();
        compareWithItk(l.write(dir / "non_finite_labels.nii"), Expect::Read, labels());
    }
}

TEST(NiftiLibRead, FourDimensionalFilesAndTheVolumeIndexAreItks) {
    const auto dir = scratchDir("nifti_4d");
    Nifti1 h = obliqueQform();
    h.dim[0] = 4;
    h.dim[4] = 3;
    const fs::path file = h.write(dir / "frames.nii.gz");
    compareWithItk(file, Expect::Read, volume(0));
    compareWithItk(file, Expect::Read, volume(2));
    compareWithItk(file, Expect::LeftToItk);  // refused: which volume?
    compareWithItk(file, Expect::LeftToItk, volume(3));
    {  // 4-D with one volume is 3-D; 5-D with a trailing 1 is 4-D
        Nifti1 one;
        one.dim[0] = 4;
        compareWithItk(one.write(dir / "one_frame.nii"), Expect::Read);
        compareWithItk(dir / "one_frame.nii", Expect::LeftToItk, volume(1));
        Nifti1 five = h;
        five.dim[0] = 5;
        compareWithItk(five.write(dir / "five_d.nii"), Expect::Read, volume(1));
    }
}

TEST(NiftiLibRead, WhatLibniftiCannotReadAsItkIsLeftToIt) {
    const auto dir = scratchDir("nifti_itk_only");
    {  // vectors, complex voxels, 2-D images: ITK reads or refuses them
        Nifti1 vec;
        vec.dim[0] = 5;
        vec.dim[5] = 2;
        vec.intent = 1007;  // NIFTI_INTENT_VECTOR
        compareWithItk(vec.write(dir / "vectors.nii"), Expect::LeftToItk, volume(1));
        Nifti1 complex;
        complex.datatype = 32;
        compareWithItk(complex.write(dir / "complex.nii"), Expect::LeftToItk);
        Nifti1 flat;
        flat.dim[0] = 2;
        flat.dim[3] = 1;
        compareWithItk(flat.write(dir / "flat.nii"), Expect::LeftToItk);
    }
    {  // an Analyze header in a .nii file, and "DICM" where DICOM marks its files
        Nifti1 analyze;
        std::memset(analyze.magic, 0, 4);
        compareWithItk(analyze.write(dir / "analyze.nii"), Expect::LeftToItk);
        std::string dicm = Nifti1().bytes();
        std::memcpy(dicm.data() + 128, "DICM", 4);
        writeBytes(dir / "dicm.nii", dicm);
        compareWithItk(dir / "dicm.nii", Expect::LeftToItk);
    }
    {  // a region: ITK reads it alone
        LoadOptions o;
        o.region = openvdb::CoordBBox(openvdb::Coord(1, 1, 1), openvdb::Coord(4, 3, 2));
        compareWithItk(obliqueQform().write(dir / "region.nii"), Expect::LeftToItk, o);
    }
    {  // cut short, and longer than the header says: isohex's checks refuse it on ITK's path
        const std::string b = obliqueQform().bytes();
        writeBytes(dir / "short.nii", b.substr(0, b.size() - 10));
        compareWithItk(dir / "short.nii", Expect::LeftToItk);
        writeBytes(dir / "long.nii", b + std::string(8, '\0'));
        compareWithItk(dir / "long.nii", Expect::LeftToItk);
    }
}

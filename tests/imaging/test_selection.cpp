// select() and ImplicitField: iso / Otsu / labels, smoothing, value,
// gradient, projection, thread safety.
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <random>

#include <tbb/parallel_for.h>

#include "TestSupport.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/imaging/Selection.hpp"
#include "isohex/imaging/Volume.hpp"

using namespace isohex::imaging;
using namespace isohex::imaging::test;
using isohex::Vec3;

namespace {

double norm(const Vec3& a) { return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }
Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }

Vec3 centreOf(const Volume& v, int i, int j, int k) {
    const auto w = v.transform().indexToWorld(openvdb::Coord(i, j, k));
    return {w[0], w[1], w[2]};
}

// A ball of radius R (world units) around world point C, as the float image
// R - |x - C| sampled on a rotated, anisotropic grid, written to NRRD.
struct Ball {
    Vec3 centre;
    double radius = 6.0;
    Volume volume;
};

Ball makeBall(const fs::path& dir) {
    Geometry g;
    g.origin = {5.0, -3.0, 12.0};
    g.spacing = {0.6, 0.5, 0.8};
    const double c = std::cos(0.4), s = std::sin(0.4);
    g.direction = {c, -s, 0, s, c, 0, 0, 0, 1};  // rotated about z
    const Dims dims{32, 34, 24};
    Ball ball;
    ball.centre = itkPhysicalPoint(g, {16, 17, 12});
    std::vector<float> v;
    for (int k = 0; k < dims[2]; ++k)
        for (int j = 0; j < dims[1]; ++j)
            for (int i = 0; i < dims[0]; ++i) {
                const auto p = itkPhysicalPoint(g, {i, j, k});
                v.push_back(float(ball.radius - norm(sub({p[0], p[1], p[2]}, ball.centre))));
            }
    writeImage(dir / "ball.nrrd", dims, v, g);
    ball.volume = loadVolume(dir / "ball.nrrd");
    return ball;
}

}  // namespace

TEST(Selection, GivenIsoFieldIsIsoMinusIntensityAtVoxelCentres) {
    const Volume vol = loadVolume(sharedData() / "skull_ct.nii.gz");
    SelectOptions o;
    o.iso = 2.9;
    const Selection sel = select(vol, o);
    ASSERT_EQ(sel.materials.size(), 1u);
    EXPECT_FALSE(sel.isoFromOtsu);
    EXPECT_DOUBLE_EQ(*sel.iso, 2.9);
    const auto& f = sel.materials[0].field;
    auto acc = vol.intensity->getConstAccessor();
    for (auto c : {openvdb::Coord(10, 20, 30), openvdb::Coord(32, 32, 32), openvdb::Coord(0, 63, 5)})
        EXPECT_NEAR(f.value(centreOf(vol, c.x(), c.y(), c.z())), 2.9 - acc.getValue(c), 1e-5);
    EXPECT_GT(sel.materials[0].voxels, 0);
    // Outside the scanned box the field is outside.
    EXPECT_GT(f.value(centreOf(vol, -5, 30, 30)), 0.0);
}

TEST(Selection, InsideBelowFlipsTheSign) {
    const Volume vol = loadVolume(sharedData() / "skull_ct.nii.gz");
    SelectOptions o;
    o.iso = 2.9;
    const Selection above = select(vol, o);
    o.insideBelow = true;
    const Selection below = select(vol, o);
    const Vec3 p = centreOf(vol, 30, 31, 29);
    EXPECT_NEAR(above.materials[0].field.value(p), -below.materials[0].field.value(p), 1e-6);
    EXPECT_EQ(above.materials[0].voxels + below.materials[0].voxels, vol.voxelCount());
}

TEST(Selection, WithoutIsoOtsuChoosesAndReportsTheLevel) {
    const Volume vol = loadVolume(sharedData() / "skull_ct.nii.gz");
    const Selection sel = select(vol);
    ASSERT_TRUE(sel.iso.has_value());
    EXPECT_TRUE(sel.isoFromOtsu);
    EXPECT_GT(*sel.iso, vol.minValue);
    EXPECT_LT(*sel.iso, vol.maxValue);
    // Otsu splits a two-level image between its levels.
    const auto dir = scratchDir("otsu");
    std::vector<float> two(8 * 8 * 8, 10.0f);
    for (std::size_t i = 0; i < two.size(); i += 3) two[i] = 50.0f;
    writeImage(dir / "two.nrrd", {8, 8, 8}, two, Geometry{});
    const Selection s2 = select(loadVolume(dir / "two.nrrd"));
    EXPECT_GT(*s2.iso, 10.0);
    EXPECT_LT(*s2.iso, 50.0);
    fs::remove_all(dir);
}

TEST(ImplicitField, ProjectionLandsOnABallInARotatedAnisotropicGrid) {
    const auto dir = scratchDir("ball");
    const Ball ball = makeBall(dir);
    SelectOptions o;
    o.iso = 0.0;
    for (auto interp : {Interpolation::Trilinear, Interpolation::Quadratic}) {
        o.interpolation = interp;
        const Selection sel = select(ball.volume, o);
        const auto& f = sel.materials.at(0).field;
        std::mt19937 rng(3);
        std::uniform_real_distribution<double> u(-1.0, 1.0);
        for (int n = 0; n < 200; ++n) {
            Vec3 d{u(rng), u(rng), u(rng)};
            const double len = norm(d);
            if (len < 0.1) continue;
            const double r = ball.radius + 2.0 * u(rng);  // within 2 mm of the surface
            const Vec3 start{ball.centre[0] + d[0] / len * r, ball.centre[1] + d[1] / len * r,
                             ball.centre[2] + d[2] / len * r};
            const Projection p = f.projectDetailed(start);
            ASSERT_TRUE(p.converged);
            EXPECT_NEAR(std::fabs(f.value(p.point)), 0.0, 1e-3);
            EXPECT_NEAR(norm(sub(p.point, ball.centre)), ball.radius, 0.05);
            // The gradient points outwards (the field grows outside).
            const Vec3 g = f.gradient(start);
            const Vec3 out = sub(start, ball.centre);
            // Intensity falls outwards, so the field (iso - intensity) rises:
            // its gradient is the outward normal.
            EXPECT_GT((g[0] * out[0] + g[1] * out[1] + g[2] * out[2]) / (norm(g) * norm(out)), 0.95);
        }
    }
    fs::remove_all(dir);
}

TEST(ImplicitField, GradientMatchesFiniteDifferencesInWorldSpace) {
    const auto dir = scratchDir("grad");
    const Ball ball = makeBall(dir);
    SelectOptions o;
    o.iso = 0.0;
    const Selection sel = select(ball.volume, o);
    const auto& f = sel.materials.at(0).field;
    const Vec3 x{ball.centre[0] + 2.13, ball.centre[1] - 3.07, ball.centre[2] + 1.91};
    const Vec3 g = f.gradient(x);
    const double h = 1e-4;
    for (int a = 0; a < 3; ++a) {
        Vec3 lo = x, hi = x;
        lo[a] -= h;
        hi[a] += h;
        EXPECT_NEAR(g[a], (f.value(hi) - f.value(lo)) / (2 * h), 1e-3);
    }
    // |grad| of a distance-like field is about 1 per mm.
    EXPECT_NEAR(norm(g), 1.0, 0.05);
    fs::remove_all(dir);
}

TEST(ImplicitField, ProjectionTakesTheNearCrossingOfAThickSlab) {
    // Intensity 1 - ((z-12)/4)^2: inside (> 0) for 8 < z < 16. Near the slab's
    // middle the gradient is tiny and a plain Newton step would fly far away;
    // the safeguarded projection walks to the nearest crossing.
    const auto dir = scratchDir("slab");
    std::vector<float> v;
    for (int z = 0; z < 24; ++z)
        for (int y = 0; y < 6; ++y)
            for (int x = 0; x < 6; ++x) v.push_back(float(1.0 - ((z - 12.0) / 4.0) * ((z - 12.0) / 4.0)));
    writeImage(dir / "slab.nrrd", {6, 6, 24}, v, Geometry{});
    SelectOptions o;
    o.iso = 0.0;
    const Selection sel = select(loadVolume(dir / "slab.nrrd"), o);
    const auto& f = sel.materials.at(0).field;
    ProjectOptions po;
    po.maxDistanceVoxels = 20;
    const Projection lower = f.projectDetailed({2.5, 2.5, 11.9}, po);
    ASSERT_TRUE(lower.converged);
    EXPECT_NEAR(lower.point[2], 8.0, 0.1);
    const Projection upper = f.projectDetailed({2.5, 2.5, 12.2}, po);
    ASSERT_TRUE(upper.converged);
    EXPECT_NEAR(upper.point[2], 16.0, 0.1);
    // A point in a flat region (no gradient) reports failure instead of guessing.
    std::vector<float> flat(6 * 6 * 24, 0.0f);
    for (int i = 0; i < 36 * 4; ++i) flat[i] = 1.0f;
    writeImage(dir / "flat.nrrd", {6, 6, 24}, flat, Geometry{});
    o.iso = 0.5;
    const Selection flatSel = select(loadVolume(dir / "flat.nrrd"), o);
    const auto& g = flatSel.materials.at(0).field;
    EXPECT_FALSE(g.projectDetailed({2.5, 2.5, 15.0}).converged);
    fs::remove_all(dir);
}

TEST(ImplicitField, ConcurrentQueriesMatchSerialOnes) {
    const auto dir = scratchDir("threads");
    const Ball ball = makeBall(dir);
    SelectOptions o;
    o.iso = 0.0;
    const Selection sel = select(ball.volume, o);
    const auto& f = sel.materials.at(0).field;
    std::vector<Vec3> starts;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-8.0, 8.0);
    for (int n = 0; n < 4000; ++n) starts.push_back({ball.centre[0] + u(rng), ball.centre[1] + u(rng), ball.centre[2] + u(rng)});
    std::vector<Vec3> serial(starts.size()), parallel(starts.size());
    for (std::size_t i = 0; i < starts.size(); ++i) serial[i] = f.project(starts[i]);
    tbb::parallel_for(std::size_t(0), starts.size(), [&](std::size_t i) { parallel[i] = f.project(starts[i]); });
    EXPECT_EQ(serial, parallel);
    fs::remove_all(dir);
}

TEST(Selection, EveryAtlasLabelBecomesAMaterialAndTinyOnesAreReported) {
    LoadOptions lo;
    lo.labels = true;
    const Volume vol = loadVolume(sharedData() / "JHU-WhiteMatter-labels-2mm.nii.gz", lo);
    SelectOptions o;
    o.minLabelVoxels = 1;
    const Selection all = select(vol, o);
    EXPECT_EQ(all.materials.size(), 48u);
    EXPECT_TRUE(all.dropped.empty());
    auto acc = vol.labels->getConstAccessor();
    for (const auto& m : all.materials) {
        // Find one voxel of the label: the field is inside there.
        bool checked = false;
        for (auto c = vol.box.begin(); c && !checked; ++c) {
            if (acc.getValue(*c) != m.id) continue;
            EXPECT_LT(m.field.value(centreOf(vol, (*c).x(), (*c).y(), (*c).z())), 0.0) << m.id;
            checked = true;
        }
        EXPECT_TRUE(checked);
        EXPECT_GT(m.field.value(centreOf(vol, 0, 0, 0)), 0.0) << m.id;  // background corner
    }
    // The voxel counts of the materials add up to the non-zero voxels.
    std::int64_t nonZero = 0;
    for (auto c = vol.box.begin(); c; ++c) nonZero += acc.getValue(*c) != 0;
    std::int64_t sum = 0;
    for (const auto& m : all.materials) sum += m.voxels;
    EXPECT_EQ(sum, nonZero);

    // Raise the threshold above the smallest tract: it is dropped and reported.
    std::int64_t smallest = all.materials.front().voxels;
    for (const auto& m : all.materials) smallest = std::min(smallest, m.voxels);
    o.minLabelVoxels = smallest + 1;
    const Selection some = select(vol, o);
    ASSERT_FALSE(some.dropped.empty());
    EXPECT_EQ(some.materials.size() + some.dropped.size(), 48u);
    for (const auto& d : some.dropped) EXPECT_LT(d.voxels, o.minLabelVoxels);

    o.labels = {5, 12};
    o.minLabelVoxels = 1;
    const Selection two = select(vol, o);
    ASSERT_EQ(two.materials.size(), 2u);
    EXPECT_EQ(two.materials[0].id, 5);
    EXPECT_EQ(two.materials[1].id, 12);
}

TEST(Selection, LabelSurfaceSitsHalfWayBetweenVoxelCentres) {
    const auto dir = scratchDir("cube_label");
    std::vector<std::uint8_t> l(10 * 10 * 10, 0);
    for (int z = 3; z < 7; ++z)
        for (int y = 3; y < 7; ++y)
            for (int x = 3; x < 7; ++x) l[x + 10 * (y + 10 * z)] = 2;
    Geometry g;
    g.spacing = {1.0, 2.0, 0.5};
    writeImage(dir / "cube.nii.gz", {10, 10, 10}, l, g);
    LoadOptions lo;
    lo.labels = true;
    const Volume vol = loadVolume(dir / "cube.nii.gz", lo);
    const Selection sel = select(vol);
    const auto& f = sel.materials.at(0).field;
    EXPECT_EQ(sel.materials[0].id, 2);
    EXPECT_EQ(sel.materials[0].voxels, 64);
    // Between index 6 (label) and 7 (background) along x: x = 6.5 mm.
    EXPECT_NEAR(f.value({6.5, 9.0, 2.5}), 0.0, 1e-6);
    const Vec3 p = f.project({7.2, 9.0, 2.5});
    EXPECT_NEAR(p[0], 6.5, 1e-4);
    fs::remove_all(dir);
}

TEST(Selection, GaussianSmoothingUsesMillimetresPerAxis) {
    // An impulse blurred with sigma 2 mm on a 1 x 2 x 0.5 mm grid has a
    // standard deviation of 2, 1 and 4 voxels along x, y and z.
    const openvdb::Coord dims(41, 41, 41);
    std::vector<float> v(41 * 41 * 41, 0.0f);
    v[20 + 41 * (20 + 41 * 20)] = 1.0f;
    gaussianSmooth(v, dims, {1.0, 2.0, 0.5}, 2.0);
    double sum = 0, var[3] = {0, 0, 0};
    for (int z = 0; z < 41; ++z)
        for (int y = 0; y < 41; ++y)
            for (int x = 0; x < 41; ++x) {
                const double w = v[x + 41 * (y + 41 * z)];
                sum += w;
                var[0] += w * (x - 20) * (x - 20);
                var[1] += w * (y - 20) * (y - 20);
                var[2] += w * (z - 20) * (z - 20);
            }
    EXPECT_NEAR(sum, 1.0, 1e-5);
    EXPECT_NEAR(std::sqrt(var[0]), 2.0, 0.05);
    EXPECT_NEAR(std::sqrt(var[1]), 1.0, 0.05);
    EXPECT_NEAR(std::sqrt(var[2]), 4.0, 0.1);
    // A constant stays constant (borders replicate).
    std::vector<float> c(41 * 41 * 41, 3.0f);
    gaussianSmooth(c, dims, {1.0, 2.0, 0.5}, 2.0);
    for (float x : c) ASSERT_NEAR(x, 3.0f, 1e-5);
}

TEST(Selection, SmoothingOptionSmoothsTheField) {
    const Volume vol = loadVolume(sharedData() / "skull_ct.nii.gz");
    SelectOptions o;
    o.iso = 2.9;
    const auto raw = select(vol, o);
    o.smoothSigma = 4.0;
    const auto smooth = select(vol, o);
    // Smoothing lowers the total variation of the field along a line.
    double tvRaw = 0, tvSmooth = 0;
    for (int i = 1; i < 64; ++i) {
        const Vec3 a = centreOf(vol, i - 1, 32, 32), b = centreOf(vol, i, 32, 32);
        tvRaw += std::fabs(raw.materials[0].field.value(b) - raw.materials[0].field.value(a));
        tvSmooth += std::fabs(smooth.materials[0].field.value(b) - smooth.materials[0].field.value(a));
    }
    EXPECT_LT(tvSmooth, tvRaw);
}

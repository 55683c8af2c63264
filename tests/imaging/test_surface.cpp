// Triangle surfaces: reading through Assimp, closedness checks, level sets.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <algorithm>
#include <fstream>

#include <openvdb/tools/LevelSetMeasure.h>

#include "TestSupport.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/imaging/Surface.hpp"

using namespace isohex::imaging;
using namespace isohex::imaging::test;
using isohex::Vec3;

namespace {

// A unit cube [0,2]^3 with outward triangles; `skip` drops triangles,
// `flip` reverses some, `inward` reverses all.
struct Cube {
    std::vector<Vec3> v{{0, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0}, {0, 0, 2}, {2, 0, 2}, {2, 2, 2}, {0, 2, 2}};
    std::vector<std::array<int, 3>> t{{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                                      {1, 2, 6}, {1, 6, 5}, {2, 3, 7}, {2, 7, 6}, {3, 0, 4}, {3, 4, 7}};
};

void writeOff(const fs::path& p, const Cube& c) {
    std::ofstream o(p);
    o << "OFF\n" << c.v.size() << " " << c.t.size() << " 0\n";
    for (const auto& x : c.v) o << x[0] << " " << x[1] << " " << x[2] << "\n";
    for (const auto& t : c.t) o << "3 " << t[0] << " " << t[1] << " " << t[2] << "\n";
}

Vec3 normalOf(const Cube& c, const std::array<int, 3>& t) {
    const auto &a = c.v[t[0]], &b = c.v[t[1]], &d = c.v[t[2]];
    const Vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w{d[0] - a[0], d[1] - a[1], d[2] - a[2]};
    return {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
}

void writeAsciiStl(const fs::path& p, const Cube& c) {
    std::ofstream o(p);
    o << "solid cube\n";
    for (const auto& t : c.t) {
        const Vec3 n = normalOf(c, t);
        o << " facet normal " << n[0] << " " << n[1] << " " << n[2] << "\n  outer loop\n";
        for (int k : t) o << "   vertex " << c.v[k][0] << " " << c.v[k][1] << " " << c.v[k][2] << "\n";
        o << "  endloop\n endfacet\n";
    }
    o << "endsolid cube\n";
}

void writeBinaryStl(const fs::path& p, const Cube& c) {
    std::ofstream o(p, std::ios::binary);
    char header[80] = "binary cube";
    o.write(header, 80);
    const std::uint32_t n = std::uint32_t(c.t.size());
    o.write(reinterpret_cast<const char*>(&n), 4);
    for (const auto& t : c.t) {
        const Vec3 nn = normalOf(c, t);
        float f[12] = {float(nn[0]), float(nn[1]), float(nn[2])};
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) f[3 + 3 * k + a] = float(c.v[t[k]][a]);
        o.write(reinterpret_cast<const char*>(f), sizeof f);
        const std::uint16_t attr = 0;
        o.write(reinterpret_cast<const char*>(&attr), 2);
    }
}

void writeObj(const fs::path& p, const Cube& c) {
    std::ofstream o(p);
    for (const auto& x : c.v) o << "v " << x[0] << " " << x[1] << " " << x[2] << "\n";
    for (const auto& t : c.t) o << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
}

void writePly(const fs::path& p, const Cube& c) {
    std::ofstream o(p);
    o << "ply\nformat ascii 1.0\nelement vertex " << c.v.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nelement face " << c.t.size()
      << "\nproperty list uchar int vertex_indices\nend_header\n";
    for (const auto& x : c.v) o << x[0] << " " << x[1] << " " << x[2] << "\n";
    for (const auto& t : c.t) o << "3 " << t[0] << " " << t[1] << " " << t[2] << "\n";
}

std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const isohex::Error& e) {
        return e.what();
    }
    return "no error";
}

}  // namespace

TEST(Surface, CubeReadsTheSameFromEveryFormat) {
    const auto dir = scratchDir("cube_formats");
    const Cube cube;
    writeOff(dir / "cube.off", cube);
    writeAsciiStl(dir / "cube_ascii.stl", cube);
    writeBinaryStl(dir / "cube_binary.stl", cube);
    writeObj(dir / "cube.obj", cube);
    writePly(dir / "cube.ply", cube);
    for (const char* name : {"cube.off", "cube_ascii.stl", "cube_binary.stl", "cube.obj", "cube.ply"}) {
        SCOPED_TRACE(name);
        const TriangleSurface s = loadSurface(dir / name);
        EXPECT_EQ(s.vertices.size(), 8u);  // STL corners are welded
        EXPECT_EQ(s.triangles.size(), 12u);
        EXPECT_FALSE(s.flipped);
        EXPECT_NEAR(s.volume(), 8.0, 1e-9);
        EXPECT_NEAR(s.area(), 24.0, 1e-9);
    }
    fs::remove_all(dir);
}

TEST(Surface, OpenSurfaceIsRejectedWithTheHole) {
    const auto dir = scratchDir("open");
    Cube cube;
    cube.t.pop_back();
    cube.t.pop_back();  // remove one face of the cube
    writeOff(dir / "open.off", cube);
    const std::string msg = errorOf([&] { loadSurface(dir / "open.off"); });
    EXPECT_NE(msg.find("open.off"), std::string::npos) << msg;
    EXPECT_NE(msg.find("open: 4 edges"), std::string::npos) << msg;
    EXPECT_NE(msg.find("fill the holes"), std::string::npos) << msg;
    fs::remove_all(dir);
}

TEST(Surface, InconsistentOrientationIsRejected) {
    const auto dir = scratchDir("inconsistent");
    Cube cube;
    std::swap(cube.t[2][1], cube.t[2][2]);
    writeOff(dir / "twisted.off", cube);
    const std::string msg = errorOf([&] { loadSurface(dir / "twisted.off"); });
    EXPECT_NE(msg.find("orientation is inconsistent"), std::string::npos) << msg;
    fs::remove_all(dir);
}

TEST(Surface, NonManifoldEdgeIsRejected) {
    const auto dir = scratchDir("nonmanifold");
    Cube cube;
    // A fin: an extra pair of triangles hanging on the cube's edge 0-1.
    cube.v.push_back({1, -2, -2});
    cube.t.push_back({0, 1, 8});
    cube.t.push_back({1, 0, 8});
    writeOff(dir / "fin.off", cube);
    const std::string msg = errorOf([&] { loadSurface(dir / "fin.off"); });
    EXPECT_NE(msg.find("not manifold"), std::string::npos) << msg;
    fs::remove_all(dir);
}

TEST(Surface, InwardSurfaceIsFlipped) {
    const auto dir = scratchDir("inward");
    Cube cube;
    for (auto& t : cube.t) std::swap(t[1], t[2]);
    writeOff(dir / "inward.off", cube);
    const TriangleSurface s = loadSurface(dir / "inward.off");
    EXPECT_TRUE(s.flipped);
    EXPECT_NEAR(s.volume(), 8.0, 1e-9);
    fs::remove_all(dir);
}

TEST(Surface, MissingAndUnreadableFilesAreReported) {
    EXPECT_NE(errorOf([] { loadSurface("/nonexistent/bone.stl"); }).find("no such file"), std::string::npos);
    const auto dir = scratchDir("junk");
    std::ofstream(dir / "junk.stl") << "this is not a surface";
    const std::string msg = errorOf([&] { loadSurface(dir / "junk.stl"); });
    EXPECT_NE(msg.find("junk.stl"), std::string::npos) << msg;
    EXPECT_NE(msg.find("cannot be read"), std::string::npos) << msg;
    fs::remove_all(dir);
}

TEST(Surface, SphereLevelSetHasTheRightSignAndVolume) {
    TriangleSurface s = loadSurface(sharedData() / "sphere966.off");
    Vec3 c{0, 0, 0};
    for (const auto& p : s.vertices)
        for (int a = 0; a < 3; ++a) c[a] += p[a] / double(s.vertices.size());
    double r = 0;
    for (const auto& p : s.vertices)
        r += std::sqrt((p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
                       (p[2] - c[2]) * (p[2] - c[2])) / double(s.vertices.size());
    const double sphere = 4.0 / 3.0 * M_PI * r * r * r;
    EXPECT_NEAR(s.volume(), sphere, 0.03 * sphere);  // the polyhedron is slightly inside the sphere

    LevelSetOptions o;
    o.elementSize = r / 10.0;
    const SurfaceLevelSet ls = surfaceToLevelSet(s, o);
    EXPECT_NEAR(ls.voxelSize, r / 20.0, 1e-12);
    EXPECT_EQ(ls.grid->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_LT(ls.field.value(c), 0.0);
    EXPECT_GT(ls.field.value({c[0] + 1.5 * r, c[1], c[2]}), 0.0);
    EXPECT_LT(ls.field.value({c[0] + 0.9 * r, c[1], c[2]}), 0.0);
    EXPECT_GT(ls.field.value({c[0], c[1] - 1.1 * r, c[2]}), 0.0);
    const double volume = openvdb::tools::levelSetVolume(*ls.grid);
    EXPECT_NEAR(volume, s.volume(), 0.01 * s.volume());
    EXPECT_NEAR(volume, sphere, 0.03 * sphere);
    // Mesh vertices lie on the zero set (within a small part of a voxel).
    for (std::size_t i = 0; i < s.vertices.size(); i += 7)
        EXPECT_LT(std::fabs(ls.field.value(s.vertices[i])), 0.1 * ls.voxelSize);
    EXPECT_EQ(ls.surface.triangles.size(), s.triangles.size());
}

TEST(Surface, FemurIsClosedAndItsVerticesProjectOntoTheLevelSet) {
    TriangleSurface s = loadSurface(sharedData() / "femur.off");
    EXPECT_EQ(s.vertices.size(), 3897u);
    EXPECT_GT(s.volume(), 0.0);
    Vec3 lo = s.vertices[0], hi = lo;
    for (const auto& p : s.vertices)
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
    LevelSetOptions o;
    o.elementSize = (hi[2] - lo[2]) / 40.0;
    const SurfaceLevelSet ls = surfaceToLevelSet(s, o);
    EXPECT_NEAR(openvdb::tools::levelSetVolume(*ls.grid), s.volume(), 0.03 * s.volume());
    {
        std::vector<double> dev;
        for (const auto& p : s.vertices) dev.push_back(std::fabs(ls.field.value(p)) / ls.voxelSize);
        std::sort(dev.begin(), dev.end());
        // Measured: median 0.10, 95th percentile 1.05, max 1.84 voxels, and
        // the same with a wider band or a filled interior; the sphere stays
        // below 0.1 everywhere. Not explained yet (self-intersections in the
        // femur resolved as a union are one suspect). Pinned so a change shows.
        EXPECT_LT(dev[dev.size() / 2], 0.2) << dev[dev.size() * 95 / 100] << " " << dev.back();
        EXPECT_LT(dev.back(), 2.5);
    }
    for (std::size_t i = 0; i < s.vertices.size(); i += 13) {
        const auto& p = s.vertices[i];
        const Vec3 q{p[0] + 0.3 * ls.voxelSize, p[1] - 0.2 * ls.voxelSize, p[2]};
        const Projection pr = ls.field.projectDetailed(q);
        ASSERT_TRUE(pr.converged);
        EXPECT_LT(std::fabs(ls.field.value(pr.point)), 1e-3 * ls.voxelSize);
        // Bounded by the deviation above plus the 0.36-voxel offset: no jump
        // to another part of the bone (which is > 10 voxels away).
        EXPECT_LT(pr.distance, 4.0 * ls.voxelSize);
    }
}

// The extraction (octree labels + dual contouring, before the sheet and the
// optimiser) on the phantoms and the real scans, checked against things
// isohex does not compute itself:
//  * the topology (components, Euler characteristic) of every material's
//    boundary against that of OpenVDB's volumeToMesh surface of the same
//    field sampled at the grid points isohex uses;
//    and of the field after repair (RepairedDomain), the surface the mesh follows;
//  * the distance of boundary corners to the field's zero set (the repaired
//    field's in cells the repair changed, the labels' union's where the
//    outside meets several labels);
//  * validate() on ch2bet at 2 mm and 1 mm with --keep-largest.
// Figures are printed with the prefix "[figures]" (bench and reports quote them).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>
#include <openvdb/openvdb.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/core/VecMath.hpp"
#include "isohex/octree/DualContour.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/GridEdits.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/PolygonRegions.hpp"
#include "isohex/octree/Regions.hpp"
#include "isohex/octree/TopologyMatch.hpp"
#include "isohex/pipeline/Contour.hpp"
#include "isohex/pipeline/Fidelity.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "isohex/pipeline/Pillow.hpp"
#include "isohex/pipeline/Prepare.hpp"

using namespace isohex;

namespace {

std::string sharedData() {
    if (const char* env = std::getenv("ISOHEX_SHARED_DATA")) return env;
    return "../shared/data";
}
std::string phantoms() {
    if (const char* env = std::getenv("ISOHEX_PHANTOMS")) return env;
    return ISOHEX_PHANTOMS_DIR;
}

struct QuietSink : pipeline::StageSink {
    void begin(std::string_view) override {}
    void progress(double) override {}
    void end(std::string_view, double) override {}
    void note(std::string_view, const std::string&) override {}
};

struct Extracted {
    pipeline::Prepared p;
    HexMesh mesh;
    octree::ExtractStats stats;
};

Extracted extractOnly(const std::string& input, pipeline::MeshSettings s) {
    if (!std::filesystem::exists(input)) throw std::runtime_error("missing input " + input);
    s.pillow = false;
    s.optimize = false;
    s.tangledStart = false;  // these tests check the valid start's held-back positions, whatever the default
    QuietSink sink;
    Extracted r;
    r.p = pipeline::prepare(input, s, sink);
    // what pipeline::contour does without --mesh-exterior, keeping the statistics
    r.mesh = octree::dualContourHexes(r.p.labels, r.p.extractionDomain(), {}, &r.stats);
    return r;
}

// Components and Euler characteristic V - E + F of a polygon surface given
// by vertex ids (vertices shared between polygons by id).
struct SurfaceTopology {
    std::size_t components = 0;
    long long euler = 0;
    std::size_t faces = 0;
};

template <class Polygons>
SurfaceTopology polygonTopology(const Polygons& polys) {
    std::map<std::size_t, std::size_t> vid;  // compact vertex ids
    DisjointSets<std::size_t> sets;
    auto id = [&](std::size_t v) {
        auto [it, fresh] = vid.emplace(v, sets.size());
        if (fresh) sets.add();
        return it->second;
    };
    std::set<std::pair<std::size_t, std::size_t>> edges;
    SurfaceTopology t;
    for (const auto& poly : polys) {
        ++t.faces;
        const std::size_t n = poly.size();
        for (std::size_t i = 0; i < n; ++i) {
            const std::size_t a = id(poly[i]), b = id(poly[(i + 1) % n]);
            edges.emplace(std::min(a, b), std::max(a, b));
            sets.unite(a, b);
        }
    }
    t.components = sets.countSets();
    t.euler = static_cast<long long>(sets.size()) - static_cast<long long>(edges.size()) +
              static_cast<long long>(t.faces);
    return t;
}

// The boundary of material m's hexes: boundary quads of its hexes and the
// interface quads it shares with another material.
SurfaceTopology meshRegionTopology(const HexMesh& mesh, const Topology& topo, std::int32_t m) {
    std::vector<std::vector<std::size_t>> polys;
    for (const Quad& q : topo.quads) {
        const std::int32_t a = mesh.material[q.hex[0]];
        const std::int32_t b = q.boundary() ? -1 : mesh.material[q.hex[1]];
        if (a == b || (a != m && b != m)) continue;
        polys.push_back({static_cast<std::size_t>(q.nodes[0]), static_cast<std::size_t>(q.nodes[1]),
                         static_cast<std::size_t>(q.nodes[2]), static_cast<std::size_t>(q.nodes[3])});
    }
    return polygonTopology(polys);
}

// The field sampled at the extraction grid's points (the grid's outer layer
// outside, as sampleLabels does), as an OpenVDB grid with the grid's own
// (possibly anisotropic, oblique) transform.
template <class Field>
openvdb::FloatGrid::Ptr sampleOnGrid(const octree::Grid& g, const Field& value) {
    openvdb::math::Mat4d mat = openvdb::math::Mat4d::identity();
    for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) mat(a, c) = g.axes[a][c];
    for (int c = 0; c < 3; ++c) mat(3, c) = g.origin[c];
    auto grid = openvdb::FloatGrid::create(1.0f);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(mat));
    const auto [nx, ny, nz] = g.dims;
    std::vector<float> v(g.size(), 1.0f);
    tbb::parallel_for(1, nz - 1, [&](int k) {
        for (int j = 1; j < ny - 1; ++j)
            for (int i = 1; i < nx - 1; ++i) v[g.index(i, j, k)] = static_cast<float>(value(g.point(i, j, k)));
    });
    auto acc = grid->getAccessor();
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) acc.setValue(openvdb::Coord(i, j, k), v[g.index(i, j, k)]);
    return grid;
}

SurfaceTopology vdbTopology(const openvdb::FloatGrid& grid) {
    std::vector<openvdb::Vec3s> pts;
    std::vector<openvdb::Vec3I> tris;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(grid, pts, tris, quads, 0.0);
    std::vector<std::vector<std::size_t>> polys;
    for (const auto& t : tris) polys.push_back({t[0], t[1], t[2]});
    for (const auto& q : quads) polys.push_back({q[0], q[1], q[2], q[3]});
    return polygonTopology(polys);
}

// volumeToMesh's surface of material m's grid points (inside; all others outside).
SurfaceTopology labelSurface(const octree::Labels& l, std::int32_t m) {
    auto grid = openvdb::FloatGrid::create(1.0f);
    auto acc = grid->getAccessor();
    const auto [nx, ny, nz] = l.grid.dims;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                if (l.material[l.grid.index(i, j, k)] == m) acc.setValue(openvdb::Coord(i, j, k), -1.0f);
    return vdbTopology(*grid);
}

// Distances (in voxels of the scan) of the corners of every boundary quad
// against the outside to their isosurface, by kind of corner: the labels of
// its cell's 8 grid points differ from a fresh sampling of the scan
// (non-manifold repair or --keep-largest changed them; measured against the
// repaired field, and against the scan's for the record), or the move onto
// the surface inverted a hex so the pipeline starts it from a held-back
// position (ExtractStats::heldBack), or the cell holds three or more
// materials (measured against the union of the labels), or none of these
// ("plain").
struct CornerFigures {
    std::size_t plain = 0, changed = 0, multi = 0, held = 0;
    std::size_t plainOver = 0, changedOver = 0, multiOver = 0, heldOver = 0;  // beyond 0.1 voxel
    double plainMax = 0, changedMax = 0, multiMax = 0, heldMax = 0, plainMean = 0, allMean = 0;
    // changed cells are measured against the repaired field (RepairedDomain);
    // how far their corners are from the scan's own isosurface, for the record
    std::size_t changedScanOver = 0;
    double changedScanMax = 0;
    std::size_t all() const { return plain + changed + multi + held; }
};

CornerFigures cornerDistances(const Extracted& r) {
    const HexMesh& mesh = r.mesh;
    const Topology topo = buildTopology(mesh);
    const octree::Grid& g = r.p.labels.grid;
    const octree::Labels fresh = octree::sampleLabels(*r.p.domain, g);
    // node -> the material whose outer boundary it is a corner of (first seen)
    std::vector<std::int32_t> boundaryOf(mesh.nodeCount(), 0);
    for (Index q : topo.boundaryQuads)
        for (Index v : topo.quads[q].nodes)
            if (boundaryOf[v] == 0) boundaryOf[v] = mesh.material[topo.quads[q].hex[0]];
    std::vector<Index> nodes;
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v)
        if (boundaryOf[v] > 0) nodes.push_back(static_cast<Index>(v));
    // world -> cell: cell c spans grid points c-1 .. c
    const double* ax[3] = {g.axes[0].data(), g.axes[1].data(), g.axes[2].data()};
    const double det = g.determinant();
    double inv[3][3];
    for (int a = 0; a < 3; ++a) {
        const double* u = ax[(a + 1) % 3];
        const double* w = ax[(a + 2) % 3];
        inv[a][0] = (u[1] * w[2] - u[2] * w[1]) / det;
        inv[a][1] = (u[2] * w[0] - u[0] * w[2]) / det;
        inv[a][2] = (u[0] * w[1] - u[1] * w[0]) / det;
    }
    const auto& sel = *r.p.selection;
    std::vector<double> dist(nodes.size()), scanDist(nodes.size());
    std::vector<int> kind(nodes.size());
    const octree::Domain& repaired = r.p.extractionDomain();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nodes.size()), [&](const auto& range) {
        for (std::size_t n = range.begin(); n != range.end(); ++n) {
            const Vec3& x = mesh.nodes[nodes[n]];
            const imaging::ImplicitField* f = nullptr;
            for (const auto& m : sel.materials)
                if (m.id == boundaryOf[nodes[n]]) f = &m.field;
            imaging::ProjectOptions o;
            o.maxDistanceVoxels = 20;
            const imaging::Projection pr = f->projectDetailed(x, o);
            // Not converged: no surface found within 20 voxels (a flat field
            // around the corner), unless a segment to a grid point of the
            // cell where the field has the other sign crosses it (Newton can
            // step over a blob a hair wide around one grid point).
            double best = pr.converged ? pr.distance : 20.0 * f->voxelSize();
            int c[3];
            const Vec3 d{x[0] - g.origin[0], x[1] - g.origin[1], x[2] - g.origin[2]};
            for (int a = 0; a < 3; ++a) c[a] = static_cast<int>(std::floor(inv[a][0] * d[0] + inv[a][1] * d[1] + inv[a][2] * d[2])) + 1;
            const double fx = f->value(x);
            for (int k = 0; k < 8; ++k) {
                const Vec3 q = g.point(c[0] - 1 + (k & 1), c[1] - 1 + (k >> 1 & 1), c[2] - 1 + (k >> 2 & 1));
                if ((f->value(q) < 0) == (fx < 0)) continue;
                double t0 = 0, t1 = 1;  // bisection: the sign at t0 is that of x
                for (int it = 0; it < 60; ++it) {
                    const double t = 0.5 * (t0 + t1);
                    const Vec3 y{x[0] + t * (q[0] - x[0]), x[1] + t * (q[1] - x[1]), x[2] + t * (q[2] - x[2])};
                    ((f->value(y) < 0) == (fx < 0) ? t0 : t1) = t;
                }
                const double len = std::sqrt((q[0] - x[0]) * (q[0] - x[0]) + (q[1] - x[1]) * (q[1] - x[1]) + (q[2] - x[2]) * (q[2] - x[2]));
                best = std::min(best, t1 * len);
            }
            dist[n] = scanDist[n] = best / f->voxelSize();
            bool changed = false;
            std::set<std::int32_t> mats;
            for (int k = 0; k < 8; ++k) {
                const int i = c[0] - 1 + (k & 1), j = c[1] - 1 + (k >> 1 & 1), l = c[2] - 1 + (k >> 2 & 1);
                const bool in = i >= 0 && j >= 0 && l >= 0 && i < g.dims[0] && j < g.dims[1] && l < g.dims[2];
                const std::int32_t now = in ? r.p.labels.material[g.index(i, j, l)] : 0;
                const std::int32_t was = in ? fresh.material[g.index(i, j, l)] : 0;
                changed = changed || now != was;
                mats.insert(now);
            }
            const bool held = std::binary_search(r.stats.heldBack.begin(), r.stats.heldBack.end(), nodes[n]);
            kind[n] = changed ? 1 : held ? 3 : mats.size() > 2 ? 2 : 0;
            // Distance bound to the zero set of `field`: a segment from x to a
            // grid point of the cell where the field has the other sign crosses
            // it; the first sign change in 256 steps along it, then bisection.
            auto bisected = [&](const auto& field) {
                const double fx0 = field(x);
                if (fx0 == 0) return 0.0;
                double bestHere = std::numeric_limits<double>::infinity();
                for (int k = 0; k < 8; ++k) {
                    const Vec3 q = g.point(c[0] - 1 + (k & 1), c[1] - 1 + (k >> 1 & 1), c[2] - 1 + (k >> 2 & 1));
                    if ((field(q) < 0) == (fx0 < 0)) continue;
                    double t0 = 0, t1 = 1;
                    for (int step = 1; step <= 256; ++step) {
                        const double t = step / 256.0;
                        const Vec3 y{x[0] + t * (q[0] - x[0]), x[1] + t * (q[1] - x[1]), x[2] + t * (q[2] - x[2])};
                        if ((field(y) < 0) != (fx0 < 0)) {
                            t1 = t;
                            break;
                        }
                        t0 = t;
                    }
                    for (int it = 0; it < 60; ++it) {
                        const double t = 0.5 * (t0 + t1);
                        const Vec3 y{x[0] + t * (q[0] - x[0]), x[1] + t * (q[1] - x[1]), x[2] + t * (q[2] - x[2])};
                        ((field(y) < 0) == (fx0 < 0) ? t0 : t1) = t;
                    }
                    const double len = std::sqrt((q[0] - x[0]) * (q[0] - x[0]) + (q[1] - x[1]) * (q[1] - x[1]) + (q[2] - x[2]) * (q[2] - x[2]));
                    bestHere = std::min(bestHere, t1 * len);
                }
                // and a sign change within 0.1 voxel along the 26 grid
                // directions or the gradient: the zero set is at most that far
                const double r0 = 0.1 * f->voxelSize();
                std::vector<Vec3> dirs;
                for (int a = -1; a <= 1; ++a)
                    for (int b = -1; b <= 1; ++b)
                        for (int e = -1; e <= 1; ++e)
                            if (a || b || e) dirs.push_back({double(a), double(b), double(e)});
                {
                    const double hd = 1e-3 * f->voxelSize();
                    Vec3 gr;
                    for (int a = 0; a < 3; ++a) {
                        Vec3 p1 = x, p0 = x;
                        p1[a] += hd;
                        p0[a] -= hd;
                        gr[a] = field(p1) - field(p0);
                    }
                    dirs.push_back(gr);
                    dirs.push_back({-gr[0], -gr[1], -gr[2]});
                }
                for (const Vec3& d : dirs) {
                    const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                    if (!(len > 0)) continue;
                    for (int step = 1; step <= 16; ++step) {
                        const double t = r0 * step / 16.0 / len;
                        if (t * len >= bestHere) break;
                        const Vec3 y{x[0] + t * d[0], x[1] + t * d[1], x[2] + t * d[2]};
                        if ((field(y) < 0) != (fx0 < 0)) {
                            bestHere = std::min(bestHere, t * len);
                            break;
                        }
                    }
                }
                return bestHere / f->voxelSize();
            };
            if (mats.size() > 2) {
                // the outside meets two or more labels: the outer surface there
                // is the labelled region's as a whole (the union's isosurface)
                dist[n] = bisected([&](const Vec3& y) { return repaired.unionValue(y); });
            } else if (changed) {
                // the repaired field has its label's sign at every grid point
                const std::int32_t m = boundaryOf[nodes[n]];
                dist[n] = bisected([&](const Vec3& y) { return repaired.value(m, y); });
            }
        }
    });
    CornerFigures f;
    for (std::size_t n = 0; n < nodes.size(); ++n) {
        const double d = dist[n];
        const bool over = d > 0.1;
        f.allMean += d;
        if (kind[n] == 1) {
            ++f.changed;
            f.changedOver += over;
            f.changedMax = std::max(f.changedMax, d);
            f.changedScanOver += scanDist[n] > 0.1;
            f.changedScanMax = std::max(f.changedScanMax, scanDist[n]);
        } else if (kind[n] == 3) {
            ++f.held;
            f.heldOver += over;
            f.heldMax = std::max(f.heldMax, d);
        } else if (kind[n] == 2) {
            ++f.multi;
            f.multiOver += over;
            f.multiMax = std::max(f.multiMax, d);
        } else {
            ++f.plain;
            f.plainOver += over;
            f.plainMax = std::max(f.plainMax, d);
            f.plainMean += d;
        }
    }
    f.allMean /= std::max<std::size_t>(nodes.size(), 1);
    f.plainMean /= std::max<std::size_t>(f.plain, 1);
    return f;
}

void print(const std::string& name, const CornerFigures& c) {
    std::cout << "[figures] " << name << " corners: plain " << c.plain << " (>0.1 vox: " << c.plainOver
              << ", max " << c.plainMax << ", mean " << c.plainMean << "), changed-by-repair " << c.changed
              << " (>0.1 from the repaired field's zero set: " << c.changedOver << ", max " << c.changedMax
              << "; from the scan's: " << c.changedScanOver << ", max " << c.changedScanMax << "), 3+ materials " << c.multi
              << " (>0.1: " << c.multiOver << ", max " << c.multiMax << "), held back to keep hexes valid " << c.held
              << " (>0.1: " << c.heldOver << ", max " << c.heldMax << "), mean all " << c.allMean << "\n";
}

// Every boundary corner within 0.1 voxel of its isosurface: the scan's, the
// repaired field's in cells the repair changed, the union of the labels' where
// the outside meets two or more labels; held-back corners included (the mesh
// has them on the surface, their valid position is only in ExtractStats).
void expectOnTheIsosurface(const std::string& name, const CornerFigures& f) {
    EXPECT_EQ(f.plainOver, 0u) << name << ": max " << f.plainMax;
    EXPECT_EQ(f.changedOver, 0u) << name << ": max " << f.changedMax;
    EXPECT_EQ(f.multiOver, 0u) << name << ": max " << f.multiMax;
    EXPECT_EQ(f.heldOver, 0u) << name << ": max " << f.heldMax;
}

bool topologicallyValid(const HexMesh& m, std::size_t* inverted = nullptr) {
    ValidityReport v = validate(m);
    if (inverted) *inverted = v.defects.count("inverted_hex") ? v.defects.at("inverted_hex").count : 0;
    v.defects.erase("inverted_hex");
    if (!v.ok()) ADD_FAILURE() << toJson(v).dump();
    return v.ok();
}

struct Case {
    std::string name;
    std::string input;
    pipeline::MeshSettings settings;
    // False where the scan's field has points of the solid touching only along
    // an edge or at a corner in numbers (ch2bet, a noisy threshold of a whole
    // head): marching cubes (volumeToMesh) joins or keeps apart each such
    // contact by its case table, while hexes sharing an edge always touch, so
    // the repair must flip points there. It keeps volumeToMesh's parts and
    // pockets where it can (ch2bet 2 mm: 323 components, chi 542, against the
    // scan's 324 and 544; see docs/DESIGN.md, "Topology against OpenVDB");
    // with --isosurface-topology they are equal.
    // The boundary is always compared with volumeToMesh of the repaired field
    // (RepairedDomain), the surface the mesh follows.
    bool sameTopologyAsVolumeToMesh = true;
};

pipeline::MeshSettings intensity(std::optional<double> iso, std::optional<double> size, bool keepLargest = false) {
    pipeline::MeshSettings s;
    s.select.iso = iso;
    s.size = size;
    s.keepLargest = keepLargest;
    return s;
}
pipeline::MeshSettings isosurfaceTopology(pipeline::MeshSettings s) {
    s.isosurfaceTopology = true;
    return s;
}
pipeline::MeshSettings labels() {
    pipeline::MeshSettings s;
    s.load.labels = true;
    return s;
}

std::vector<Case> cases() {
    const std::string ph = phantoms() + "/", sd = sharedData() + "/";
    return {{"sphere", ph + "sphere.nii.gz", intensity(50, 1.5)},
            {"torus", ph + "torus.nii.gz", intensity(50, 1.5)},
            {"two_spheres", ph + "two_spheres.nii.gz", intensity(50, 1.5)},
            {"thin_plate", ph + "thin_plate.nii.gz", intensity(50, 1.5)},
            {"skull_ct", sd + "skull_ct.nii.gz", intensity(2.9, std::nullopt)},
            {"ch2bet_2mm", sd + "ch2bet.nii.gz", intensity(std::nullopt, 2.0), false},
            {"ch2bet_2mm_isosurface_topology", sd + "ch2bet.nii.gz", isosurfaceTopology(intensity(std::nullopt, 2.0))},
            {"jhu_labels", sd + "JHU-WhiteMatter-labels-2mm.nii.gz", labels()}};
}

class Extraction : public ::testing::TestWithParam<Case> {};

}  // namespace

// On every input: a topologically valid mesh; the components and Euler
// characteristic of every material's boundary equal those of OpenVDB's
// polygonisation of the repaired field at the same grid points, and (except
// ch2bet, see Case) of the scan's own field; and every corner of the boundary
// quads lies on its isosurface within 0.1 voxel (see CornerFigures).
TEST_P(Extraction, MatchesVolumeToMeshAndLiesOnTheIsosurface) {
    const Case& c = GetParam();
    const Extracted r = extractOnly(c.input, c.settings);
    std::size_t inverted = 0;
    EXPECT_TRUE(topologicallyValid(r.mesh, &inverted));
    EXPECT_EQ(octree::countNonManifoldBlocks(r.p.labels), 0u);
    const Topology topo = buildTopology(r.mesh);
    std::cout << "[figures] " << c.name << " labels as sampled: "
              << octree::describe(octree::regionTopology(octree::sampleLabels(*r.p.domain, r.p.labels.grid)))
              << "; repaired: " << octree::describe(octree::regionTopology(r.p.labels)) << "\n";
    const octree::Domain& repaired = r.p.extractionDomain();
    for (const auto& m : r.p.selection->materials) {
        const SurfaceTopology ours = meshRegionTopology(r.mesh, topo, m.id);
        const SurfaceTopology vdb =
            vdbTopology(*sampleOnGrid(r.p.labels.grid, [&](const Vec3& x) { return m.field.value(x); }));
        const SurfaceTopology vdbRepaired =
            vdbTopology(*sampleOnGrid(r.p.labels.grid, [&](const Vec3& x) { return repaired.value(m.id, x); }));
        std::cout << "[figures] " << c.name << " material " << m.id << ": isohex " << ours.components
                  << " components, chi " << ours.euler << "; volumeToMesh of the scan's field " << vdb.components
                  << " components, chi " << vdb.euler << "; of the repaired field " << vdbRepaired.components
                  << " components, chi " << vdbRepaired.euler << "\n";
        // the surface the mesh follows
        EXPECT_EQ(ours.components, vdbRepaired.components) << c.name << " material " << m.id;
        EXPECT_EQ(ours.euler, vdbRepaired.euler) << c.name << " material " << m.id;
        if (c.sameTopologyAsVolumeToMesh) {
            EXPECT_EQ(ours.components, vdb.components) << c.name << " material " << m.id;
            EXPECT_EQ(ours.euler, vdb.euler) << c.name << " material " << m.id;
        }
    }
    const CornerFigures f = cornerDistances(r);
    print(c.name, f);
    HexMesh heldBack = r.mesh;  // as the pipeline goes on: held-back vertices at their valid positions
    for (std::size_t i = 0; i < r.stats.heldBack.size(); ++i) heldBack.nodes[r.stats.heldBack[i]] = r.stats.heldBackAt[i];
    const ValidityReport vh = validate(heldBack);
    std::cout << "[figures] " << c.name << " hexes " << r.mesh.hexCount() << ", inverted " << inverted
              << " (with the held-back positions "
              << (vh.defects.count("inverted_hex") ? vh.defects.at("inverted_hex").count : 0) << ")\n";
    // the mesh the sheet and the optimiser start from has no inverted hex
    EXPECT_EQ(vh.defects.count("inverted_hex"), 0u) << c.name;
    expectOnTheIsosurface(c.name, f);
}

// The repair's preferred flips keep the topology of the surface volumeToMesh
// draws: octree::flipKeepsPolygonTopology decides from the points around a
// flip; here every verdict on random labellings (one and two materials, dense
// in edge and corner contacts, where the 26/6 digital model and marching
// cubes disagree) is checked against volumeToMesh of the whole grid before
// and after the flip. A flip it accepts changes neither the components nor
// the Euler characteristic of either material's surface, and the Euler
// change it reports is the polygonisation's.
TEST(Repair, PolygonTopologyTestAgreesWithVolumeToMesh) {
    const octree::CellEdgeGroups& table = octree::volumeToMeshTables();
    std::mt19937 rng(20261123);
    std::size_t kept = 0, changed = 0;
    for (int materials : {1, 2})
        for (int trial = 0; trial < 150; ++trial) {
            octree::Labels l;
            l.grid.dims = {11, 11, 11};
            l.grid.origin = {0, 0, 0};
            l.grid.axes = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
            l.material.assign(l.grid.size(), 0);
            std::uniform_real_distribution<double> u(0, 1);
            const double density = 0.3 + 0.4 * u(rng);
            for (int k = 1; k < 10; ++k)
                for (int j = 1; j < 10; ++j)
                    for (int i = 1; i < 10; ++i)
                        if (u(rng) < density)
                            l.material[l.grid.index(i, j, k)] = materials == 1 ? 1 : 1 + static_cast<int>(u(rng) * 2);
            std::uniform_int_distribution<int> inner(3, 7);  // the whole 9^3 window inside the grid
            for (int flip = 0; flip < 10; ++flip) {
                const int i = inner(rng), j = inner(rng), k = inner(rng);
                const std::int32_t from = l.material[l.grid.index(i, j, k)];
                std::int32_t to = static_cast<std::int32_t>(u(rng) * (materials + 1));
                if (to == from) to = (to + 1) % (materials + 1);
                long long dchi = 0;
                const bool keeps = octree::flipKeepsPolygonTopology(l, i, j, k, to, table, &dchi);
                std::map<std::int32_t, SurfaceTopology> before, after;
                for (std::int32_t m : {from, to})
                    if (m != 0) before[m] = labelSurface(l, m);
                l.material[l.grid.index(i, j, k)] = to;
                long long actual = 0;
                bool same = true;
                for (auto& [m, t] : before) {
                    after[m] = labelSurface(l, m);
                    actual += after[m].euler - t.euler;
                    same = same && after[m].components == t.components && after[m].euler == t.euler;
                }
                EXPECT_EQ(dchi, actual) << "trial " << trial << " point " << i << "," << j << "," << k;
                if (keeps) {
                    EXPECT_TRUE(same) << "trial " << trial << " point " << i << "," << j << "," << k;
                }
                (same ? kept : changed) += 1;
            }
        }
    // the random labellings exercise both verdicts
    EXPECT_GT(kept, 100u);
    EXPECT_GT(changed, 100u);
}

// --isosurface-topology: after the repair, matchPolygonTopology re-chooses
// the repair's changes. On random blobby labellings (smoothed noise cut at
// a level, one and two materials, with many edge and corner contacts): the
// result is manifold, and wherever the report says every group whose change
// altered the surface was mended, every material's boundary has the
// components and Euler characteristic of volumeToMesh's surface of the
// sampled labels; the repair alone misses it in many of those cases.
TEST(Repair, IsosurfaceTopologyMatchesVolumeToMeshWhereItMends) {
    // the labels as a domain: |value| grows away from the level, the sign is the label
    // (two materials: the solid split by a plane)
    struct GridDomain : octree::Domain {
        const octree::Labels* l;
        const std::vector<float>* noise;
        std::size_t at(const Vec3& x) const {
            const auto [nx, ny, nz] = l->grid.dims;
            const int i = std::clamp(static_cast<int>(std::lround(x[0])), 0, nx - 1);
            const int j = std::clamp(static_cast<int>(std::lround(x[1])), 0, ny - 1);
            const int k = std::clamp(static_cast<int>(std::lround(x[2])), 0, nz - 1);
            return l->grid.index(i, j, k);
        }
        std::int32_t materialAt(const Vec3& x) const override { return l->material[at(x)]; }
        double value(std::int32_t m, const Vec3& x, Vec3* gradient) const override {
            if (gradient) *gradient = {0, 0, 0};
            const double v = std::abs((*noise)[at(x)]) + 0.01;
            return l->material[at(x)] == m ? -v : v;
        }
    };
    std::mt19937 rng(20261202);
    std::uniform_real_distribution<double> u(0, 1);
    int mendedAll = 0, repairAloneDiffers = 0, searched = 0;
    for (int materials : {1, 2})
        for (int trial = 0; trial < 60; ++trial) {
            const int n = 14;
            octree::Labels l;
            l.grid.dims = {n, n, n};
            l.grid.origin = {0, 0, 0};
            l.grid.axes = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
            l.material.assign(l.grid.size(), 0);
            // noise smoothed twice over 3x3x3, cut at a level chosen per trial
            std::vector<float> raw(l.grid.size()), noise(l.grid.size(), 0.0f);
            for (auto& v : raw) v = static_cast<float>(u(rng) - 0.5);
            for (int pass = 0; pass < 2; ++pass) {
                std::fill(noise.begin(), noise.end(), 0.0f);
                for (int k = 1; k < n - 1; ++k)
                    for (int j = 1; j < n - 1; ++j)
                        for (int i = 1; i < n - 1; ++i) {
                            float sum = 0;
                            for (int q = 0; q < 27; ++q)
                                sum += raw[l.grid.index(i + q % 3 - 1, j + q / 3 % 3 - 1, k + q / 9 - 1)];
                            noise[l.grid.index(i, j, k)] = sum / 27.0f;
                        }
                if (pass == 0) raw = noise;
            }
            const float level = static_cast<float>(0.01 * (u(rng) - 0.5));
            for (int k = 1; k < n - 1; ++k)
                for (int j = 1; j < n - 1; ++j)
                    for (int i = 1; i < n - 1; ++i) {
                        const std::size_t p = l.grid.index(i, j, k);
                        if (noise[p] - level < 0)
                            l.material[p] = materials == 1 ? 1 : 1 + (2 * i + j > 3 * n / 2);
                    }
            GridDomain d;
            d.l = &l;
            d.noise = &noise;
            const octree::Labels sampled = l;
            octree::Labels repaired = l;
            octree::repairNonManifold(repaired, d);
            octree::Labels matched = repaired;
            const octree::TopologyMatchReport rep =
                octree::matchPolygonTopology(matched, sampled, d, octree::volumeToMeshTables());
            const std::string where = std::to_string(materials) + " material(s), trial " + std::to_string(trial);
            EXPECT_EQ(octree::countNonManifoldBlocks(matched), 0u) << where;
            EXPECT_FALSE(rep.discarded) << where;
            searched += rep.groupsChanging > 0;
            EXPECT_EQ(rep.groupsChanging - rep.groupsMatched, rep.unmended.size()) << where;
            const bool mended = rep.groupsChanging == rep.groupsMatched;
            mendedAll += mended;
            bool repairSame = true;
            long long eulerOff = 0, named = 0;
            for (const auto& place : rep.unmended) named += place.eulerChange;
            for (std::int32_t m = 1; m <= materials; ++m) {
                const SurfaceTopology want = labelSurface(sampled, m);
                auto topologyOf = [&](const octree::Labels& x) {
                    for (const auto& t : octree::regionTopology(x))
                        if (t.material == m) return std::make_pair(static_cast<long long>(t.components), t.euler);
                    return std::make_pair(0LL, 0LL);
                };
                const auto got = topologyOf(matched), alone = topologyOf(repaired);
                eulerOff += got.second - want.euler;
                repairSame = repairSame && alone.first == static_cast<long long>(want.components) && alone.second == want.euler;
                if (!mended) continue;
                EXPECT_EQ(got.first, static_cast<long long>(want.components)) << where << ", material " << m;
                EXPECT_EQ(got.second, want.euler) << where << ", material " << m;
            }
            // every accepted step is exact: what is off is what the places
            // the report names change
            EXPECT_EQ(named, eulerOff) << where;
            if (mended) repairAloneDiffers += !repairSame;
        }
    std::cout << "[figures] isosurface topology on random labellings: " << searched << " of 120 searched, "
              << mendedAll << " with every group mended, " << repairAloneDiffers
              << " of those where the repair alone differs from volumeToMesh\n";
    // (measured: 82 searched, 119 with every group mended, 79 of them where
    // the repair alone differs; 118 without the annealing, 109 without the
    // whole deep search)
    EXPECT_GE(mendedAll, 119);
    EXPECT_GE(repairAloneDiffers, 60);
}

// Label maps: each label's surface is the 0.5 level of its trilinear
// indicator. Those surfaces do not tile the labelled region: where three
// labels meet, or two labels and the background, every label's isosurface
// cuts the corner, and the gap between them belongs to no label. The mesh is
// a partition (every point of the labelled region in exactly one hex), so its
// total volume is compared with the 0.5-isosurface of the union of the
// selected labels, and each label's volume with its voxels' volume.
TEST(Labels, JhuVolumeAgainstTheUnionIsosurfaceAndTheVoxels) {
    const Extracted r = extractOnly(sharedData() + "/JHU-WhiteMatter-labels-2mm.nii.gz", labels());
    const auto& vol = *r.p.volume;
    std::map<std::int32_t, double> meshVolume;
    for (std::size_t h = 0; h < r.mesh.hexCount(); ++h)
        meshVolume[r.mesh.material[h]] += hexVolume(hexCoords(r.mesh, static_cast<Index>(h)));
    std::set<std::int32_t> selected;
    for (const auto& m : r.p.selection->materials) selected.insert(m.id);
    // the union's indicator: 0.5 - [label selected] per voxel
    auto unionField = openvdb::FloatGrid::create(0.5f);
    unionField->setTransform(vol.labels->transform().copy());
    {
        auto in = vol.labels->getConstAccessor();
        auto out = unionField->getAccessor();
        openvdb::CoordBBox box = vol.box;
        box.expand(1);
        for (auto it = box.begin(); it; ++it) out.setValue(*it, selected.count(in.getValue(*it)) ? -0.5f : 0.5f);
    }
    const double unionIso = pipeline::isosurfaceVolume(*unionField);
    const double voxel = vol.spacing[0] * vol.spacing[1] * vol.spacing[2];
    double meshTotal = 0, labelIsoTotal = 0, voxelTotal = 0, worstVoxelChange = 0;
    for (const auto& m : r.p.selection->materials) {
        const double iso = pipeline::isosurfaceVolume(m.field.grid());
        const double vox = static_cast<double>(m.voxels) * voxel;
        meshTotal += meshVolume[m.id];
        labelIsoTotal += iso;
        voxelTotal += vox;
        worstVoxelChange = std::max(worstVoxelChange, std::abs(meshVolume[m.id] - vox) / vox);
        std::cout << "[figures] jhu label " << m.id << ": mesh " << meshVolume[m.id] << ", 0.5-isosurface " << iso
                  << " (" << 100 * (meshVolume[m.id] - iso) / iso << "%), voxels " << vox << " ("
                  << 100 * (meshVolume[m.id] - vox) / vox << "%)\n";
    }
    std::cout << "[figures] jhu total: mesh " << meshTotal << "; union 0.5-isosurface " << unionIso << " ("
              << 100 * (meshTotal - unionIso) / unionIso << "%); sum of the labels' 0.5-isosurfaces " << labelIsoTotal
              << " (" << 100 * (meshTotal - labelIsoTotal) / labelIsoTotal << "%); voxels " << voxelTotal << " ("
              << 100 * (meshTotal - voxelTotal) / voxelTotal << "%); worst label vs its voxels "
              << 100 * worstVoxelChange << "%\n";
    EXPECT_LT(std::abs(meshTotal - unionIso) / unionIso, 0.02);
}

// Issue 4: the brain with --keep-largest at 2 mm and 1 mm (about 1.7 million
// hexes) has no non-manifold place left, a valid mesh, a boundary whose
// topology is that of the repaired labels and of volumeToMesh of the repaired
// field, and corners on the isosurface.
TEST(Ch2bet, KeepLargestIsManifoldAndValidAtTwoAndOneMillimetre) {
    for (double size : {2.0, 1.0}) {
        const std::string name = "ch2bet_keep_largest_" + std::to_string(static_cast<int>(size)) + "mm";
        const Extracted r = extractOnly(sharedData() + "/ch2bet.nii.gz", intensity(std::nullopt, size, true));
        EXPECT_EQ(octree::countNonManifoldBlocks(r.p.labels), 0u) << name;
        std::size_t inverted = 0;
        EXPECT_TRUE(topologicallyValid(r.mesh, &inverted)) << name;
        const auto labelsTopology = octree::regionTopology(r.p.labels);
        ASSERT_EQ(labelsTopology.size(), 1u);
        const SurfaceTopology ours = meshRegionTopology(r.mesh, buildTopology(r.mesh), 1);
        EXPECT_EQ(ours.components, labelsTopology[0].components) << name;
        EXPECT_EQ(ours.euler, labelsTopology[0].euler) << name;
        const octree::Domain& repaired = r.p.extractionDomain();
        const SurfaceTopology vdb =
            vdbTopology(*sampleOnGrid(r.p.labels.grid, [&](const Vec3& x) { return repaired.value(1, x); }));
        EXPECT_EQ(ours.components, vdb.components) << name;
        EXPECT_EQ(ours.euler, vdb.euler) << name;
        const CornerFigures f = cornerDistances(r);
        print(name, f);
        std::cout << "[figures] " << name << " hexes " << r.mesh.hexCount() << ", inverted " << inverted << ", "
                  << ours.components << " boundary components, chi " << ours.euler
                  << "; volumeToMesh of the repaired field " << vdb.components << ", chi " << vdb.euler << "\n";
        expectOnTheIsosurface(name, f);
    }
}

// ch2bet against volumeToMesh of the scan's own field (not the repaired one)
// at the extraction grid's points, with and without --keep-largest (then the
// field outside the kept points is taken as outside). The repair does not
// match it exactly yet (issue 4; see docs/DESIGN.md, "Topology against
// OpenVDB"): the test holds the gap to what the repair reaches now, so a
// change that widens it fails. The boundary's topology is that of the
// repaired labels (regionTopology; the tests above check the mesh against it).
TEST(Ch2bet, TopologyNearVolumeToMeshOfTheScanAtTwoAndOneMillimetre) {
    std::map<std::string, std::vector<std::int32_t>> repairOnly;  // labels without the option, by case
    struct Bound {
        double size;
        bool keepLargest;
        bool isosurfaceTopology;
        long long components, euler;  // largest |ours - volumeToMesh| allowed
    };
    // measured (components/chi, ours against volumeToMesh's): the repair alone
    // 2 mm 323/542 against 324/544, with --keep-largest 297/492 against
    // 299/494; 1 mm 591/848 against 594/878, with --keep-largest 483/632
    // against 491/674. With --isosurface-topology all four are equal: 1 mm
    // since the deep search, 2 mm (324/544, 299/494) since its annealing.
    for (const Bound& b : {Bound{2.0, false, false, 1, 2}, Bound{2.0, true, false, 2, 2}, Bound{1.0, false, false, 3, 30},
                           Bound{1.0, true, false, 8, 42}, Bound{2.0, false, true, 0, 0}, Bound{2.0, true, true, 0, 0},
                           Bound{1.0, false, true, 0, 0}, Bound{1.0, true, true, 0, 0}}) {
        // (2 mm without --keep-largest: the repair alone is within 1 and 2;
        // the option must still change the repair's labels, checked below)
        const std::string name = "ch2bet_" + std::string(b.keepLargest ? "keep_largest_" : "") +
                                 std::to_string(static_cast<int>(b.size)) + "mm" +
                                 (b.isosurfaceTopology ? "_isosurface_topology" : "");
        pipeline::MeshSettings s = intensity(std::nullopt, b.size, b.keepLargest);
        s.isosurfaceTopology = b.isosurfaceTopology;
        QuietSink sink;
        const pipeline::Prepared p = pipeline::prepare(sharedData() + "/ch2bet.nii.gz", s, sink);
        EXPECT_EQ(octree::countNonManifoldBlocks(p.labels), 0u) << name;
        const std::string plainKey = std::to_string(b.size) + (b.keepLargest ? "k" : "");
        if (!b.isosurfaceTopology) repairOnly[plainKey] = p.labels.material;
        else EXPECT_NE(p.labels.material, repairOnly.at(plainKey)) << name << ": --isosurface-topology changed nothing";
        const auto topo = octree::regionTopology(p.labels);
        ASSERT_EQ(topo.size(), 1u) << name;
        const octree::Grid& g = p.labels.grid;
        octree::Labels kept = octree::sampleLabels(*p.domain, g);
        if (b.keepLargest) octree::keepLargestComponents(kept);
        const auto& field = p.selection->materials.at(0).field;
        auto grid = sampleOnGrid(g, [&](const Vec3& x) { return field.value(x); });
        {
            // points --keep-largest dropped are outside
            auto acc = grid->getAccessor();
            const auto [nx, ny, nz] = g.dims;
            for (int k = 0; k < nz; ++k)
                for (int j = 0; j < ny; ++j)
                    for (int i = 0; i < nx; ++i)
                        if (kept.material[g.index(i, j, k)] == 0 && acc.getValue(openvdb::Coord(i, j, k)) < 0)
                            acc.setValue(openvdb::Coord(i, j, k), 1e-3f);
        }
        const SurfaceTopology vdb = vdbTopology(*grid);
        const long long dc = static_cast<long long>(topo[0].components) - static_cast<long long>(vdb.components);
        const long long de = topo[0].euler - vdb.euler;
        std::cout << "[figures] " << name << " repaired labels " << topo[0].components << " components, chi "
                  << topo[0].euler << "; volumeToMesh of the scan's field " << vdb.components << ", chi " << vdb.euler
                  << "\n";
        EXPECT_LE(std::abs(dc), b.components) << name;
        EXPECT_LE(std::abs(de), b.euler) << name;
        if (b.isosurfaceTopology) {
            // every accepted step keeps the surface exactly, so what is off is
            // what the places the report names as not mended change
            const auto& unmended = p.facts.grid.repair.isosurfaceTopology.value().unmended;
            long long named = 0;
            for (const auto& place : unmended) named += place.place.eulerChange;
            EXPECT_EQ(named, de) << name;
            EXPECT_EQ(unmended.empty(), dc == 0 && de == 0) << name;
        }
    }
}

// The extraction of a real scan is the same for any thread count (the field is
// sampled through per-thread accessors, the repair and the classification run
// in a fixed order).
TEST(Ch2bet, SameExtractionForOneAndTwoThreads) {
    Extracted one;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        one = extractOnly(sharedData() + "/ch2bet.nii.gz", intensity(std::nullopt, 2.0, true));
    }
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    const Extracted two = extractOnly(sharedData() + "/ch2bet.nii.gz", intensity(std::nullopt, 2.0, true));
    EXPECT_EQ(one.p.labels.material, two.p.labels.material);
    EXPECT_EQ(one.mesh.hexes, two.mesh.hexes);
    EXPECT_EQ(one.mesh.nodes, two.mesh.nodes);
    EXPECT_EQ(one.mesh.nodeClass, two.mesh.nodeClass);
}

INSTANTIATE_TEST_SUITE_P(Inputs, Extraction, ::testing::ValuesIn(cases()),
                         [](const auto& info) { return info.param.name; });

// Label maps: nodes where three materials meet (HexMesh::curves) slide along
// their curve in the optimiser instead of staying where extraction put them,
// and stay on both surfaces of the curve: f_q = f_r and, against the outside,
// the labels' union isosurface, else f_p = f_q (FieldProjector::projectToCurve).
TEST(LabelCurves, CurveNodesMoveAlongTheCurveWhereThreeMaterialsMeet) {
    using namespace isohex::vec;
    const std::string input = sharedData() + "/JHU-WhiteMatter-labels-2mm.nii.gz";
    ASSERT_TRUE(std::filesystem::exists(input)) << input;
    pipeline::MeshSettings s = labels();
    QuietSink sink;
    const pipeline::Prepared p = pipeline::prepare(input, s, sink);
    HexMesh mesh = pipeline::contour(p, s, sink);
    ASSERT_FALSE(mesh.curves.empty());
    pipeline::pillowBoundary(mesh, s, sink);
    const std::vector<Vec3> before = mesh.nodes;
    pipeline::optimize(mesh, p, s, sink);
    const octree::Domain& d = *p.domain;
    const double voxel = std::min({p.volume->spacing[0], p.volume->spacing[1], p.volume->spacing[2]});
    std::size_t curveNodes = 0, moved = 0, onCurve = 0;
    double worst = 0;
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v) {
        const NodeClass c = mesh.nodeClass[v];
        if (c.kind != NodeKind::Curve || c.id < 0) continue;
        ++curveNodes;
        const Vec3& x = mesh.nodes[v];
        if (x == before[v]) continue;
        ++moved;
        const auto [a, b, cc] = mesh.curves[static_cast<std::size_t>(c.id)];
        // each residual over its gradient: a distance to that surface, in voxels
        auto distance = [&](double f, const Vec3& g) { return std::abs(f) / std::max(1e-12, norm(g)) / voxel; };
        Vec3 gb, gc, ga;
        const double fb = d.value(b, x, &gb), fc = d.value(cc, x, &gc);
        const double first = distance(fb - fc, gb - gc);
        const double fa = a > 0 ? d.value(a, x, &ga) - fb : d.unionValue(x, &ga);
        const double second = distance(fa, a > 0 ? ga - gb : ga);
        const double off = std::max(first, second);
        worst = std::max(worst, off);
        onCurve += off <= 0.01;
    }
    std::cout << "[figures] JHU curve nodes " << curveNodes << ", moved " << moved << ", of those on their curve "
              << onCurve << " (farthest " << worst << " voxel)\n";
    EXPECT_GT(curveNodes, 1000u);
    EXPECT_GT(moved, curveNodes / 4);
    // released to untangle (validity before fidelity) may stay off; few
    EXPECT_GE(onCurve, moved * 95 / 100);
}

// A label map whose interface runs through grid points. The two_materials
// phantom splits its ball at x = 31.5 (half-way between voxel columns 31 and
// 32; samples/make_phantoms.py, unit spacing, origin 0), and a 1.5-voxel grid
// has points on that plane, where the two labels' fields are both exactly 0.5.
// The grid edges ending there used to count as having no crossing, so the
// interface went to the cell midpoint x = 30.75, where label 1's field is
// flat and nothing could project it back: each half of the ball was 5% off
// its volume. The interface must lie on the plane and each label keep its
// volume; and a node moved back into that flat place must count as off the
// surface in the report (the projection cannot move it, and its own position
// used to be taken as the answer: distance 0).
TEST(Labels, InterfaceThroughGridPointsStaysOnIt) {
    pipeline::MeshSettings s = labels();
    s.size = 1.5;
    const Extracted r = extractOnly(phantoms() + "/two_materials.nii.gz", s);
    ASSERT_TRUE(topologicallyValid(r.mesh));
    std::int32_t interface = -1;
    for (std::size_t k = 0; k < r.mesh.surfaces.size(); ++k)
        if (r.mesh.surfaces[k].inside == 1 && r.mesh.surfaces[k].outside == 2) interface = static_cast<std::int32_t>(k);
    ASSERT_GE(interface, 0);
    std::size_t onInterface = 0;
    double farthest = 0;
    Index someInterfaceNode = -1;
    for (std::size_t v = 0; v < r.mesh.nodeCount(); ++v) {
        const NodeClass c = r.mesh.nodeClass[v];
        if (c.kind != NodeKind::Surface || c.id != interface) continue;
        ++onInterface;
        farthest = std::max(farthest, std::abs(r.mesh.nodes[v][0] - 31.5));
        someInterfaceNode = static_cast<Index>(v);
    }
    std::cout << "[figures] two_materials at 1.5 voxels: " << onInterface
              << " nodes on the 1|2 interface, farthest from x = 31.5: " << farthest << " voxel\n";
    EXPECT_GT(onInterface, 100u);
    EXPECT_LE(farthest, 0.1);

    std::map<std::int32_t, double> meshVolume;
    for (std::size_t h = 0; h < r.mesh.hexCount(); ++h)
        meshVolume[r.mesh.material[h]] += hexVolume(hexCoords(r.mesh, static_cast<Index>(h)));
    for (const auto& m : r.p.selection->materials) {
        const double iso = pipeline::isosurfaceVolume(m.field.grid());
        std::cout << "[figures] two_materials label " << m.id << ": mesh " << meshVolume[m.id] << ", 0.5-isosurface "
                  << iso << " (" << 100 * (meshVolume[m.id] - iso) / iso << "%)\n";
        EXPECT_LT(std::abs(meshVolume[m.id] - iso) / iso, 0.02) << "label " << m.id;
    }

    // Every grid point takes the label whose field is lowest there. The
    // nearest voxel alone is not enough: at a point shared by eight voxels it
    // is one of them, whatever the other seven are, and grid edges from such a
    // point had no crossing on them (the vertices stayed where the fields are
    // flat, about a voxel off the ball: 47 surface nodes after optimisation).
    const octree::Labels sampled = octree::sampleLabels(*r.p.domain, r.p.labels.grid);
    const auto& d = sampled.grid.dims;
    std::size_t disagree = 0, labelled = 0;
    for (int k = 0; k < d[2]; ++k)
        for (int j = 0; j < d[1]; ++j)
            for (int i = 0; i < d[0]; ++i) {
                const std::int32_t a = sampled.material[sampled.grid.index(i, j, k)];
                if (a <= 0) continue;
                ++labelled;
                const Vec3 x = sampled.grid.point(i, j, k);
                const double fa = r.p.domain->value(a, x);
                for (const auto& m : r.p.selection->materials)
                    if (m.id != a && r.p.domain->value(m.id, x) < fa) {
                        ++disagree;
                        break;
                    }
            }
    std::cout << "[figures] two_materials grid points with a label whose field is not the lowest: " << disagree
              << " of " << labelled << "\n";
    EXPECT_GT(labelled, 10000u);
    EXPECT_EQ(disagree, 0u);

    const pipeline::FidelityResult before = pipeline::fidelity(r.mesh, r.p);
    HexMesh moved = r.mesh;
    moved.nodes[static_cast<std::size_t>(someInterfaceNode)][0] = 30.75;
    const pipeline::FidelityResult after = pipeline::fidelity(moved, r.p);
    EXPECT_EQ(after.boundary.notProjected, before.boundary.notProjected + 1);
}

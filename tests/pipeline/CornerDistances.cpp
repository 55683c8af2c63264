#include "CornerDistances.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <limits>
#include <set>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace isohex::testsupport {
namespace {

enum class CornerKind { Plain, Changed, Multi, Held };

// World position -> the dual cell holding it (cell c spans grid points c-1 .. c).
class CellLocator {
public:
    explicit CellLocator(const octree::Grid& g) : g_(g) {
        const double det = g.determinant();
        for (int a = 0; a < 3; ++a) {
            const auto& u = g.axes[(a + 1) % 3];
            const auto& w = g.axes[(a + 2) % 3];
            inv_[a][0] = (u[1] * w[2] - u[2] * w[1]) / det;
            inv_[a][1] = (u[2] * w[0] - u[0] * w[2]) / det;
            inv_[a][2] = (u[0] * w[1] - u[1] * w[0]) / det;
        }
    }
    std::array<int, 3> cellOf(const Vec3& x) const {
        const Vec3 d{x[0] - g_.origin[0], x[1] - g_.origin[1], x[2] - g_.origin[2]};
        std::array<int, 3> c{};
        for (int a = 0; a < 3; ++a)
            c[a] = static_cast<int>(std::floor(inv_[a][0] * d[0] + inv_[a][1] * d[1] + inv_[a][2] * d[2])) + 1;
        return c;
    }
    // The k-th of the cell's 8 grid points (bit 0: i, bit 1: j, bit 2: k).
    std::array<int, 3> cornerOf(const std::array<int, 3>& c, int k) const {
        return {c[0] - 1 + (k & 1), c[1] - 1 + (k >> 1 & 1), c[2] - 1 + (k >> 2 & 1)};
    }
    Vec3 point(const std::array<int, 3>& p) const { return g_.point(p[0], p[1], p[2]); }

private:
    const octree::Grid& g_;
    double inv_[3][3];
};

Vec3 along(const Vec3& x, const Vec3& q, double t) {
    return {x[0] + t * (q[0] - x[0]), x[1] + t * (q[1] - x[1]), x[2] + t * (q[2] - x[2])};
}
double length(const Vec3& x, const Vec3& q) {
    return std::sqrt((q[0] - x[0]) * (q[0] - x[0]) + (q[1] - x[1]) * (q[1] - x[1]) + (q[2] - x[2]) * (q[2] - x[2]));
}

// Bisection on [t0, t1] of the segment x -> q, the sign at t0 that of x.
template <class Field>
double bisect(const Field& field, const Vec3& x, const Vec3& q, bool negativeAtX, double t0, double t1) {
    for (int it = 0; it < 60; ++it) {
        const double t = 0.5 * (t0 + t1);
        ((field(along(x, q, t)) < 0) == negativeAtX ? t0 : t1) = t;
    }
    return t1 * length(x, q);
}

// Distance to the scan's isosurface: the projection's, unless a segment to a
// grid point of the cell where the field has the other sign crosses it closer
// (Newton can step over a blob a hair wide around one grid point). Not
// converged: no surface found within 20 voxels (a flat field around the corner).
double scanDistance(const imaging::ImplicitField& f, const CellLocator& cells, const Vec3& x) {
    imaging::ProjectOptions o;
    o.maxDistanceVoxels = 20;
    const imaging::Projection pr = f.projectDetailed(x, o);
    double best = pr.converged ? pr.distance : 20.0 * f.voxelSize();
    const auto c = cells.cellOf(x);
    const auto value = [&](const Vec3& y) { return f.value(y); };
    const bool negativeAtX = f.value(x) < 0;
    for (int k = 0; k < 8; ++k) {
        const Vec3 q = cells.point(cells.cornerOf(c, k));
        if ((f.value(q) < 0) == negativeAtX) continue;
        best = std::min(best, bisect(value, x, q, negativeAtX, 0, 1));
    }
    return best / f.voxelSize();
}

// The first sign change in 256 steps along each segment from x to a grid point
// of the cell with the other sign, then bisection.
template <class Field>
double segmentBound(const Field& field, const CellLocator& cells, const Vec3& x, bool negativeAtX) {
    double best = std::numeric_limits<double>::infinity();
    const auto c = cells.cellOf(x);
    for (int k = 0; k < 8; ++k) {
        const Vec3 q = cells.point(cells.cornerOf(c, k));
        if ((field(q) < 0) == negativeAtX) continue;
        double t0 = 0, t1 = 1;
        for (int step = 1; step <= 256; ++step) {
            const double t = step / 256.0;
            if ((field(along(x, q, t)) < 0) != negativeAtX) {
                t1 = t;
                break;
            }
            t0 = t;
        }
        best = std::min(best, bisect(field, x, q, negativeAtX, t0, t1));
    }
    return best;
}

// The 26 grid directions and both ways along the field's gradient at x.
template <class Field>
std::vector<Vec3> probeDirections(const Field& field, const Vec3& x, double voxel) {
    std::vector<Vec3> dirs;
    for (int a = -1; a <= 1; ++a)
        for (int b = -1; b <= 1; ++b)
            for (int e = -1; e <= 1; ++e)
                if (a || b || e) dirs.push_back({double(a), double(b), double(e)});
    const double hd = 1e-3 * voxel;
    Vec3 gr;
    for (int a = 0; a < 3; ++a) {
        Vec3 p1 = x, p0 = x;
        p1[a] += hd;
        p0[a] -= hd;
        gr[a] = field(p1) - field(p0);
    }
    dirs.push_back(gr);
    dirs.push_back({-gr[0], -gr[1], -gr[2]});
    return dirs;
}

// Distance bound (voxels) to the zero set of `field`: the segments to the
// cell's grid points of the other sign, and a sign change within 0.1 voxel
// along the probe directions (the zero set is at most that far).
template <class Field>
double zeroSetDistance(const Field& field, const CellLocator& cells, const Vec3& x, double voxel) {
    const double fx = field(x);
    if (fx == 0) return 0.0;
    double best = segmentBound(field, cells, x, fx < 0);
    const double r0 = 0.1 * voxel;
    for (const Vec3& d : probeDirections(field, x, voxel)) {
        const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (!(len > 0)) continue;
        for (int step = 1; step <= 16; ++step) {
            const double t = r0 * step / 16.0 / len;
            if (t * len >= best) break;
            if ((field(Vec3{x[0] + t * d[0], x[1] + t * d[1], x[2] + t * d[2]}) < 0) != (fx < 0)) {
                best = std::min(best, t * len);
                break;
            }
        }
    }
    return best / voxel;
}

// node -> the material whose outer boundary it is a corner of (first seen), 0 inside.
std::vector<std::int32_t> boundaryMaterials(const HexMesh& mesh, const Topology& topo) {
    std::vector<std::int32_t> boundaryOf(mesh.nodeCount(), 0);
    for (Index q : topo.boundaryQuads)
        for (Index v : topo.quads[q].nodes)
            if (boundaryOf[v] == 0) boundaryOf[v] = mesh.material[topo.quads[q].hex[0]];
    return boundaryOf;
}

struct CornerCell {
    bool changed = false;      // a label differs from a fresh sampling
    std::size_t materials = 0;  // distinct labels at the 8 points (0 outside the grid)
};

CornerCell cornerCell(const Extracted& r, const octree::Labels& fresh, const std::array<int, 3>& c,
                      const CellLocator& cells) {
    const octree::Grid& g = r.p.labels.grid;
    CornerCell out;
    std::set<std::int32_t> mats;
    for (int k = 0; k < 8; ++k) {
        const auto [i, j, l] = cells.cornerOf(c, k);
        const bool in = i >= 0 && j >= 0 && l >= 0 && i < g.dims[0] && j < g.dims[1] && l < g.dims[2];
        const std::int32_t now = in ? r.p.labels.material[g.index(i, j, l)] : 0;
        const std::int32_t was = in ? fresh.material[g.index(i, j, l)] : 0;
        out.changed = out.changed || now != was;
        mats.insert(now);
    }
    out.materials = mats.size();
    return out;
}

struct CornerMeasure {
    double distance = 0;      // against the surface its kind is measured against
    double scanDistance = 0;  // against the scan's isosurface
    CornerKind kind = CornerKind::Plain;
};

CornerFigures tally(const std::vector<CornerMeasure>& corners) {
    CornerFigures f;
    for (const CornerMeasure& m : corners) {
        const double d = m.distance;
        const bool over = d > 0.1;
        f.allMean += d;
        switch (m.kind) {
        case CornerKind::Changed:
            ++f.changed;
            f.changedOver += over;
            f.changedMax = std::max(f.changedMax, d);
            f.changedScanOver += m.scanDistance > 0.1;
            f.changedScanMax = std::max(f.changedScanMax, m.scanDistance);
            break;
        case CornerKind::Held:
            ++f.held;
            f.heldOver += over;
            f.heldMax = std::max(f.heldMax, d);
            break;
        case CornerKind::Multi:
            ++f.multi;
            f.multiOver += over;
            f.multiMax = std::max(f.multiMax, d);
            break;
        case CornerKind::Plain:
            ++f.plain;
            f.plainOver += over;
            f.plainMax = std::max(f.plainMax, d);
            f.plainMean += d;
            break;
        }
    }
    f.allMean /= std::max<std::size_t>(corners.size(), 1);
    f.plainMean /= std::max<std::size_t>(f.plain, 1);
    return f;
}

}  // namespace

CornerFigures cornerDistances(const Extracted& r) {
    const HexMesh& mesh = r.mesh;
    const Topology topo = buildTopology(mesh);
    const octree::Labels fresh = octree::sampleLabels(*r.p.domain, r.p.labels.grid);
    const std::vector<std::int32_t> boundaryOf = boundaryMaterials(mesh, topo);
    std::vector<Index> nodes;
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v)
        if (boundaryOf[v] > 0) nodes.push_back(static_cast<Index>(v));
    const CellLocator cells(r.p.labels.grid);
    const auto& sel = *r.p.selection;
    const octree::Domain& repaired = r.p.extractionDomain();
    std::vector<CornerMeasure> measured(nodes.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nodes.size()), [&](const auto& range) {
        for (std::size_t n = range.begin(); n != range.end(); ++n) {
            const Vec3& x = mesh.nodes[nodes[n]];
            const std::int32_t m = boundaryOf[nodes[n]];
            const imaging::ImplicitField* f = nullptr;
            for (const auto& mat : sel.materials)
                if (mat.id == m) f = &mat.field;
            CornerMeasure& out = measured[n];
            out.distance = out.scanDistance = scanDistance(*f, cells, x);
            const CornerCell cell = cornerCell(r, fresh, cells.cellOf(x), cells);
            const bool held = std::binary_search(r.stats.heldBack.begin(), r.stats.heldBack.end(), nodes[n]);
            out.kind = cell.changed ? CornerKind::Changed
                       : held       ? CornerKind::Held
                       : cell.materials > 2 ? CornerKind::Multi
                                            : CornerKind::Plain;
            if (cell.materials > 2) {
                // the outside meets two or more labels: the outer surface there
                // is the labelled region's as a whole (the union's isosurface)
                out.distance = zeroSetDistance([&](const Vec3& y) { return repaired.unionValue(y); }, cells, x,
                                               f->voxelSize());
            } else if (cell.changed) {
                // the repaired field has its label's sign at every grid point
                out.distance = zeroSetDistance([&](const Vec3& y) { return repaired.value(m, y); }, cells, x,
                                               f->voxelSize());
            }
        }
    });
    return tally(measured);
}

void print(const std::string& name, const CornerFigures& c) {
    std::cout << "[figures] " << name << " corners: plain " << c.plain << " (>0.1 vox: " << c.plainOver
              << ", max " << c.plainMax << ", mean " << c.plainMean << "), changed-by-repair " << c.changed
              << " (>0.1 from the repaired field's zero set: " << c.changedOver << ", max " << c.changedMax
              << "; from the scan's: " << c.changedScanOver << ", max " << c.changedScanMax << "), 3+ materials " << c.multi
              << " (>0.1: " << c.multiOver << ", max " << c.multiMax << "), held back to keep hexes valid " << c.held
              << " (>0.1: " << c.heldOver << ", max " << c.heldMax << "), mean all " << c.allMean << "\n";
}

void expectOnTheIsosurface(const std::string& name, const CornerFigures& f) {
    EXPECT_EQ(f.plainOver, 0u) << name << ": max " << f.plainMax;
    EXPECT_EQ(f.changedOver, 0u) << name << ": max " << f.changedMax;
    EXPECT_EQ(f.multiOver, 0u) << name << ": max " << f.multiMax;
    EXPECT_EQ(f.heldOver, 0u) << name << ": max " << f.heldMax;
}

}  // namespace isohex::testsupport

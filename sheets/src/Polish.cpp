#include "isohex/sheets/Polish.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/core/HexCell.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex::sheets {

namespace {

using namespace vec;

// Verdict returns 1e30 for a collapsed hex; for maximising, that is the worst.
double usableSJ(const HexCoords& x) {
    const double s = scaledJacobian(x);
    return s > 1.0 + 1e-9 ? -2.0 : s;
}

// The scaled Jacobians of the hexes around node v with v at p, summarised:
// the smallest, and the summed squared shortfall below `target`.
struct Around {
    double min = std::numeric_limits<double>::infinity();
    double shortfall = 0;
};

Around around(const HexMesh& mesh, const Topology& topo, Index v, const Vec3& p, double target) {
    Around a;
    for (const Index* h = topo.nodeHexes.begin(static_cast<std::size_t>(v)); h != topo.nodeHexes.end(static_cast<std::size_t>(v));
         ++h) {
        HexCoords x = hexCoords(mesh, *h);
        const Hex& hx = mesh.hexes[static_cast<std::size_t>(*h)];
        for (int i = 0; i < 8; ++i)
            if (hx[i] == v) x[i] = p;
        const double s = usableSJ(x);
        a.min = std::min(a.min, s);
        if (s < target) a.shortfall += (target - s) * (target - s);
    }
    return a;
}

double minAround(const HexMesh& mesh, const Topology& topo, Index v, const Vec3& p) {
    return around(mesh, topo, v, p, 0.0).min;
}

// A trial is better when it raises the smallest value, or keeps it and
// lowers the shortfall (several hexes at about the same poor value: one
// node alone cannot lift them all, but it can even them out so that the
// next node can).
bool better(const Around& trial, const Around& current) {
    if (trial.min > current.min + 1e-12) return true;
    return trial.min >= current.min && trial.shortfall < current.shortfall * (1 - 1e-9) - 1e-15;
}

// Mean length of the hex edges at v.
double edgeLengthAt(const HexMesh& mesh, const Topology& topo, Index v) {
    double sum = 0;
    int count = 0;
    const Vec3& x = mesh.nodes[static_cast<std::size_t>(v)];
    for (const Index* h = topo.nodeHexes.begin(static_cast<std::size_t>(v)); h != topo.nodeHexes.end(static_cast<std::size_t>(v));
         ++h) {
        const Hex& hx = mesh.hexes[static_cast<std::size_t>(*h)];
        for (int i = 0; i < 8; ++i) {
            if (hx[i] != v) continue;
            for (int j : hexcell::kCornerNeighbours[static_cast<std::size_t>(i)]) {
                sum += norm(mesh.nodes[static_cast<std::size_t>(hx[static_cast<std::size_t>(j)])] - x);
                ++count;
            }
        }
    }
    return count ? sum / count : 0.0;
}

// Outward unit normal of the boundary at v: the sum of its boundary quads' area vectors.
std::vector<Vec3> boundaryNormals(const HexMesh& mesh, const Topology& topo) {
    std::vector<Vec3> n(mesh.nodeCount(), Vec3{0, 0, 0});
    for (Index qi : topo.boundaryQuads) {
        const auto& q = topo.quads[static_cast<std::size_t>(qi)].nodes;
        const auto& x = mesh.nodes;
        const Vec3 a = cross(x[q[2]] - x[q[0]], x[q[3]] - x[q[1]]);
        for (Index v : q) n[v] = n[v] + a;
    }
    for (Vec3& a : n) {
        const double l = norm(a);
        if (l > 0) a = (1.0 / l) * a;
    }
    return n;
}

}  // namespace

WorstHexResult raiseWorstHexes(HexMesh& mesh, const smoothing::SurfaceProjector* projector,
                               const WorstHexOptions& opt) {
    WorstHexResult res;
    const std::size_t N = mesh.nodeCount();
    std::vector<double> sj = scaledJacobians(mesh);
    for (double& s : sj)
        if (s > 1.0 + 1e-9) s = -2.0;
    auto countBelow = [&] { return static_cast<std::size_t>(std::count_if(sj.begin(), sj.end(), [&](double s) { return s < opt.target; })); };
    res.minBefore = sj.empty() ? 0.0 : *std::min_element(sj.begin(), sj.end());
    res.belowBefore = countBelow();
    res.minAfter = res.minBefore;
    res.belowAfter = res.belowBefore;
    if (res.belowBefore == 0) return res;

    const Topology topo = buildTopology(mesh);
    auto movable = [&](Index v) {
        const NodeClass& c = mesh.nodeClass[static_cast<std::size_t>(v)];
        if (c.kind == NodeKind::Interior) return !topo.nodeOnBoundary[static_cast<std::size_t>(v)];
        return c.kind == NodeKind::Surface && projector != nullptr;
    };
    std::vector<std::uint8_t> everMoved(N, 0);
    // Directions of the compass search: the 6 axes and 8 cube diagonals in
    // 3-D; 8 directions 45 degrees apart in a tangent plane.
    std::vector<Vec3> dirs3;
    for (int i = 0; i < 3; ++i)
        for (int s = -1; s <= 1; s += 2) {
            Vec3 d{0, 0, 0};
            d[static_cast<std::size_t>(i)] = s;
            dirs3.push_back(d);
        }
    for (int a = -1; a <= 1; a += 2)
        for (int b = -1; b <= 1; b += 2)
            for (int c = -1; c <= 1; c += 2) dirs3.push_back((1.0 / std::sqrt(3.0)) * Vec3{double(a), double(b), double(c)});

    for (int round = 0; round < opt.maxRounds; ++round) {
        std::vector<Index> nodes;
        for (std::size_t h = 0; h < sj.size(); ++h)
            if (sj[h] < opt.target)
                for (Index v : mesh.hexes[h])
                    if (movable(v)) nodes.push_back(v);
        std::sort(nodes.begin(), nodes.end());
        nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
        if (nodes.empty()) break;
        std::vector<Vec3> normal;
        bool anyMove = false;
        for (Index v : nodes) {
            const auto sv = static_cast<std::size_t>(v);
            const bool surface = mesh.nodeClass[sv].kind == NodeKind::Surface;
            std::vector<Vec3> dirs = dirs3;
            if (surface) {
                if (normal.empty()) normal = boundaryNormals(mesh, topo);
                const Vec3 n = normal[sv];
                if (!(norm(n) > 0)) continue;
                // A tangent basis.
                const Vec3 helper = std::abs(n[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
                Vec3 t1 = cross(n, helper);
                t1 = (1.0 / norm(t1)) * t1;
                const Vec3 t2 = cross(n, t1);
                dirs.clear();
                for (int k = 0; k < 8; ++k) {
                    const double a = k * M_PI / 4.0;
                    dirs.push_back(std::cos(a) * t1 + std::sin(a) * t2);
                }
            }
            const double L = edgeLengthAt(mesh, topo, v);
            if (!(L > 0)) continue;
            Around best = around(mesh, topo, v, mesh.nodes[sv], opt.target);
            double step = opt.firstStep * L;
            int moves = 0;
            while (step >= opt.lastStep * L && moves < opt.maxMovesPerVisit) {
                Vec3 bestPos = mesh.nodes[sv];
                Around bestValue = best;
                for (const Vec3& d : dirs) {
                    Vec3 p = mesh.nodes[sv] + step * d;
                    if (surface) p = projector->project(mesh.nodeClass[sv].id, p);
                    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
                    const Around f = around(mesh, topo, v, p, opt.target);
                    if (better(f, bestValue)) {
                        bestValue = f;
                        bestPos = p;
                    }
                }
                if (better(bestValue, best)) {
                    mesh.nodes[sv] = bestPos;
                    best = bestValue;
                    ++moves;
                    everMoved[sv] = 1;
                    anyMove = true;
                } else {
                    step *= 0.5;
                }
            }
            if (moves)
                for (const Index* h = topo.nodeHexes.begin(sv); h != topo.nodeHexes.end(sv); ++h)
                    sj[static_cast<std::size_t>(*h)] = usableSJ(hexCoords(mesh, *h));
        }
        res.rounds = round + 1;
        if (!anyMove) break;
    }
    res.minAfter = *std::min_element(sj.begin(), sj.end());
    res.belowAfter = countBelow();
    res.nodesMoved = static_cast<std::size_t>(std::count(everMoved.begin(), everMoved.end(), 1));
    return res;
}

VolumeFitResult fitSurfaceVolume(HexMesh& mesh, const TriangleTree& triangles, std::int32_t surfaceId,
                                 const VolumeFitOptions& opt) {
    VolumeFitResult res;
    const Topology topo = buildTopology(mesh);
    auto totalVolume = [&] {
        double v = 0;
        for (std::size_t h = 0; h < mesh.hexCount(); ++h) v += hexVolume(hexCoords(mesh, static_cast<Index>(h)));
        return v;
    };
    res.volumeBefore = totalVolume();
    auto onSurface = [&](Index v) {
        const NodeClass& c = mesh.nodeClass[static_cast<std::size_t>(v)];
        return c.kind == NodeKind::Surface && c.id == surfaceId;
    };
    // The boundary quads that lie on the surface (all four corners on it).
    std::vector<std::array<Index, 4>> quads;
    for (Index qi : topo.boundaryQuads) {
        const auto& q = topo.quads[static_cast<std::size_t>(qi)].nodes;
        if (onSurface(q[0]) && onSurface(q[1]) && onSurface(q[2]) && onSurface(q[3])) quads.push_back(q);
    }
    const std::size_t N = mesh.nodeCount();
    std::vector<Index> quadsOfNode;  // CSR over nodes
    std::vector<Index> offsets(N + 1, 0);
    for (const auto& q : quads)
        for (Index v : q) ++offsets[static_cast<std::size_t>(v) + 1];
    for (std::size_t v = 0; v < N; ++v) offsets[v + 1] += offsets[v];
    quadsOfNode.resize(static_cast<std::size_t>(offsets[N]));
    {
        std::vector<Index> cursor(offsets.begin(), offsets.end() - 1);
        for (std::size_t i = 0; i < quads.size(); ++i)
            for (Index v : quads[i]) quadsOfNode[static_cast<std::size_t>(cursor[static_cast<std::size_t>(v)]++)] = static_cast<Index>(i);
    }
    std::vector<Index> nodes;
    for (std::size_t v = 0; v < N; ++v)
        if (offsets[v + 1] > offsets[v]) nodes.push_back(static_cast<Index>(v));
    res.nodes = nodes.size();
    if (nodes.empty()) {
        res.volumeAfter = res.volumeBefore;
        return res;
    }
    const std::vector<Vec3> normal = boundaryNormals(mesh, topo);
    std::vector<double> length(N, 0.0);
    for (Index v : nodes) length[static_cast<std::size_t>(v)] = edgeLengthAt(mesh, topo, v);

    // Offsets along the normals, found by Jacobi iterations on the
    // area-weighted mean signed gap between each node's quads and the
    // triangles (Simpson's rule on the bilinear quad, 3 x 3 points).
    const std::vector<Vec3> start = mesh.nodes;
    std::vector<double> offset(N, 0.0);
    auto placed = [&](Index v) {
        const auto sv = static_cast<std::size_t>(v);
        return start[sv] + offset[sv] * normal[sv];
    };
    static constexpr double w1[3] = {1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0};
    static constexpr double s1[3] = {0.0, 0.5, 1.0};
    std::vector<double> gap(quads.size()), area(quads.size());
    for (int it = 0; it < opt.iterations; ++it) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, quads.size(), 256), [&](const auto& r) {
          for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const auto& q = quads[i];
            const Vec3 x0 = placed(q[0]), x1 = placed(q[1]), x2 = placed(q[2]), x3 = placed(q[3]);
            const Vec3 an = cross(x2 - x0, x3 - x1);  // twice the area vector
            const double a = 0.5 * norm(an);
            area[i] = a;
            gap[i] = 0;
            if (!(a > 0)) continue;
            const Vec3 n = (0.5 / a) * an;
            double g = 0;
            for (int iu = 0; iu < 3; ++iu)
                for (int iv = 0; iv < 3; ++iv) {
                    const double u = s1[iu], t = s1[iv];
                    const Vec3 p = (1 - u) * (1 - t) * x0 + u * (1 - t) * x1 + u * t * x2 + (1 - u) * t * x3;
                    // Positive where the quad is outside the triangles.
                    g += w1[iu] * w1[iv] * dot(p - triangles.closestPoint(p), n);
                }
            gap[i] = g;
          }
        });
        for (Index v : nodes) {
            const auto sv = static_cast<std::size_t>(v);
            double num = 0, den = 0;
            for (Index k = offsets[sv]; k < offsets[sv + 1]; ++k) {
                const auto i = static_cast<std::size_t>(quadsOfNode[static_cast<std::size_t>(k)]);
                num += area[i] * gap[i];
                den += area[i];
            }
            if (den > 0) offset[sv] -= num / den;
            const double cap = opt.maxOffset * length[sv];
            offset[sv] = std::clamp(offset[sv], -cap, cap);
        }
    }

    // Apply in node order; each node keeps the largest of its offset, 1/2,
    // 1/4, 1/8 of it that leaves its hexes no worse than the guard allows.
    for (Index v : nodes) {
        const auto sv = static_cast<std::size_t>(v);
        if (offset[sv] == 0.0 || !(norm(normal[sv]) > 0)) continue;
        const double before = minAround(mesh, topo, v, mesh.nodes[sv]);
        const double floor = std::min(before, opt.keepScaledJacobian);
        double t = 1.0;
        bool done = false;
        for (int k = 0; k < 4 && !done; ++k, t *= 0.5) {
            const Vec3 p = mesh.nodes[sv] + (t * offset[sv]) * normal[sv];
            if (minAround(mesh, topo, v, p) >= floor) {
                mesh.nodes[sv] = p;
                res.maxOffset = std::max(res.maxOffset, std::abs(t * offset[sv]));
                ++res.nodesMoved;
                if (k > 0) ++res.nodesHeldBack;
                done = true;
            }
        }
        if (!done) ++res.nodesHeldBack;
    }
    res.volumeAfter = totalVolume();
    return res;
}

}  // namespace isohex::sheets

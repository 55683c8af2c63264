#include "isohex/smoothing/WorstHexes.hpp"

#include <algorithm>
#include <cmath>
#include <atomic>
#include <limits>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/VecMath.hpp"
#include "isohex/smoothing/Colouring.hpp"

namespace isohex::smoothing {

namespace {

using namespace vec;

// The hexes around node v with v at p, summarised for comparing positions.
struct Around {
    int inverted = 0;  // scaled Jacobian <= 0 (a corner or the centre)
    double min = std::numeric_limits<double>::infinity();
    double shortfall = 0;  // summed squared shortfall below the target
};

Around around(const HexMesh& mesh, const Topology& topo, Index v, const Vec3& p, double target) {
    Around a;
    const auto sv = static_cast<std::size_t>(v);
    for (const Index* h = topo.nodeHexes.begin(sv); h != topo.nodeHexes.end(sv); ++h) {
        HexCoords x = hexCoords(mesh, *h);
        const Hex& hx = mesh.hexes[static_cast<std::size_t>(*h)];
        for (int i = 0; i < 8; ++i)
            if (hx[static_cast<std::size_t>(i)] == v) x[static_cast<std::size_t>(i)] = p;
        const double s = usableScaledJacobian(x);
        a.inverted += !(s > 0);
        a.min = std::min(a.min, s);
        if (s < target) a.shortfall += (target - s) * (target - s);
    }
    return a;
}

bool better(const Around& trial, const Around& current) {
    if (trial.inverted != current.inverted) return trial.inverted < current.inverted;
    if (trial.min > current.min + 1e-12) return true;
    return trial.min >= current.min && trial.shortfall < current.shortfall * (1 - 1e-9) - 1e-15;
}

}  // namespace

double usableScaledJacobian(const HexCoords& x) {
    const double s = scaledJacobian(x);
    return s > 1.0 + 1e-9 ? -2.0 : s;
}

double minScaledJacobianAround(const HexMesh& mesh, const Topology& topo, Index v, const Vec3& p) {
    return around(mesh, topo, v, p, 0.0).min;
}

double meanEdgeLengthAt(const HexMesh& mesh, const Topology& topo, Index v) {
    double sum = 0;
    int count = 0;
    const auto sv = static_cast<std::size_t>(v);
    const Vec3& x = mesh.nodes[sv];
    for (const Index* h = topo.nodeHexes.begin(sv); h != topo.nodeHexes.end(sv); ++h) {
        const Hex& hx = mesh.hexes[static_cast<std::size_t>(*h)];
        for (int i = 0; i < 8; ++i) {
            if (hx[static_cast<std::size_t>(i)] != v) continue;
            for (int j : hexcell::kCornerNeighbours[static_cast<std::size_t>(i)]) {
                sum += norm(mesh.nodes[static_cast<std::size_t>(hx[static_cast<std::size_t>(j)])] - x);
                ++count;
            }
        }
    }
    return count ? sum / count : 0.0;
}

std::vector<Vec3> surfaceNormals(const HexMesh& mesh, const Topology& topo) {
    std::vector<Vec3> n(mesh.nodeCount(), Vec3{0, 0, 0});
    for (const Quad& q : topo.quads) {
        double sign = 1;  // quad nodes are in hex[0]'s order: the normal points out of hex[0]
        if (!q.boundary()) {
            const std::int32_t m0 = mesh.material[static_cast<std::size_t>(q.hex[0])];
            const std::int32_t m1 = mesh.material[static_cast<std::size_t>(q.hex[1])];
            if (m0 == m1) continue;
            if (m0 > m1) sign = -1;
        }
        const auto& x = mesh.nodes;
        const Vec3 a = sign * cross(x[q.nodes[2]] - x[q.nodes[0]], x[q.nodes[3]] - x[q.nodes[1]]);
        for (Index v : q.nodes) n[static_cast<std::size_t>(v)] = n[static_cast<std::size_t>(v)] + a;
    }
    for (Vec3& a : n) {
        const double l = norm(a);
        if (l > 0) a = (1.0 / l) * a;
    }
    return n;
}

WorstHexResult raiseWorstHexes(HexMesh& mesh, const SurfaceProjector* projector, const WorstHexOptions& opt,
                               const Topology* topology) {
    WorstHexResult res;
    const std::size_t N = mesh.nodeCount();
    std::vector<double> sj = scaledJacobians(mesh);
    for (double& s : sj)
        if (s > 1.0 + 1e-9) s = -2.0;
    auto countBelow = [&] {
        return static_cast<std::size_t>(std::count_if(sj.begin(), sj.end(), [&](double s) { return s < opt.target; }));
    };
    res.minBefore = sj.empty() ? 0.0 : *std::min_element(sj.begin(), sj.end());
    res.belowBefore = countBelow();
    res.minAfter = res.minBefore;
    res.belowAfter = res.belowBefore;
    if (res.belowBefore == 0) return res;

    Topology own;
    if (!topology) own = buildTopology(mesh);
    else if (topology->nodeHexes.offsets.size() != N + 1 || topology->hexQuads.size() != mesh.hexCount() ||
             topology->nodeOnBoundary.size() != N)
        throw Error("worst-hex pass: the topology given is not that of the mesh (" +
                    std::to_string(topology->hexQuads.size()) + " hexes against " + std::to_string(mesh.hexCount()) +
                    "); rebuild it with buildTopology()");
    const Topology& topo = topology ? *topology : own;
    auto movable = [&](Index v) {
        const NodeClass& c = mesh.nodeClass[static_cast<std::size_t>(v)];
        // (Interior-classified nodes on the boundary, Fixed nodes and Curve
        // nodes where the projector knows no curve never move.)
        if (c.kind == NodeKind::Interior) return !topo.nodeOnBoundary[static_cast<std::size_t>(v)];
        if (c.kind == NodeKind::Curve) return projector != nullptr && projector->hasCurves() && c.id >= 0;
        return c.kind == NodeKind::Surface && projector != nullptr;
    };
    std::vector<std::uint8_t> everMoved(N, 0), released(N, 0);
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
            for (int c = -1; c <= 1; c += 2)
                dirs3.push_back((1.0 / std::sqrt(3.0)) * Vec3{double(a), double(b), double(c)});

    // One node's compass search; true if it moved.
    // With `release`, a surface node moves in 3-D, off its surface, but stays
    // within releaseDistance local edge lengths of it.
    auto visit = [&](Index v, const std::vector<Vec3>& normal, bool release) {
        const auto sv = static_cast<std::size_t>(v);
        const bool surface = mesh.nodeClass[sv].kind == NodeKind::Surface;
        const bool curve = mesh.nodeClass[sv].kind == NodeKind::Curve;
        if (curve && release) return false;  // curve nodes stay on their curve
        const bool onSurface = surface && !release;
        std::vector<Vec3> dirs = dirs3;
        if (onSurface) {
            const Vec3 n = normal[sv];
            if (!(norm(n) > 0)) return false;
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
        const double L = meanEdgeLengthAt(mesh, topo, v);
        if (!(L > 0)) return false;
        Around best = around(mesh, topo, v, mesh.nodes[sv], opt.target);
        double step = opt.firstStep * L;
        int moves = 0;
        while (step >= opt.lastStep * L && moves < opt.maxMovesPerVisit) {
            Vec3 bestPos = mesh.nodes[sv];
            Around bestValue = best;
            for (const Vec3& d : dirs) {
                Vec3 p = mesh.nodes[sv] + step * d;
                if (onSurface) p = projector->project(mesh.nodeClass[sv].id, p);
                // a curve node: the 3-D trial point onto its curve (both ways along it)
                if (curve) p = projector->projectToCurve(mesh.nodeClass[sv].id, p);
                if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
                if (surface && release &&
                    !(norm(projector->project(mesh.nodeClass[sv].id, p) - p) <= opt.releaseDistance * L))
                    continue;
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
            } else {
                step *= 0.5;
            }
        }
        if (!moves) return false;
        everMoved[sv] = 1;
        if (surface && release) released[sv] = 1;
        for (const Index* h = topo.nodeHexes.begin(sv); h != topo.nodeHexes.end(sv); ++h)
            sj[static_cast<std::size_t>(*h)] = usableScaledJacobian(hexCoords(mesh, *h));
        return true;
    };

    // Tangent planes from the surfaces as they are at the start (the nodes
    // move by fractions of an element).
    const std::vector<Vec3> normal = surfaceNormals(mesh, topo);
    // Rounds over the nodes of the hexes below the target until nothing moves;
    // then, if hexes are still inverted, rounds over theirs only, where
    // surface nodes may leave their surface (validity before fidelity: a fold
    // of the surface within one element cannot be opened along it).
    auto runRound = [&](bool release) {
        std::vector<Index> nodes;
        for (std::size_t h = 0; h < sj.size(); ++h)
            if (release ? !(sj[h] > 0) : sj[h] < opt.target)
                for (Index v : mesh.hexes[h])
                    if (movable(v)) nodes.push_back(v);
        std::sort(nodes.begin(), nodes.end());
        nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
        if (nodes.empty()) return false;
        // Nodes sharing no hex move at once: one colour class per parallel
        // loop, classes in order, so the result is the same for any number
        // of threads.
        std::vector<std::uint8_t> pick(N, 0);
        for (Index v : nodes) pick[static_cast<std::size_t>(v)] = 1;
        const NodeColouring colouring = colourNodes(mesh, topo.nodeHexes, pick);
        std::atomic<bool> anyMove{false};
        for (const std::vector<Index>& cls : colouring.classes)
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, cls.size(), 16), [&](const auto& range) {
                for (std::size_t i = range.begin(); i != range.end(); ++i)
                    if (visit(cls[i], normal, release)) anyMove = true;
            });
        ++res.rounds;
        return anyMove.load();
    };
    for (int round = 0; round < opt.maxRounds && runRound(false); ++round) {
    }
    if (projector != nullptr && opt.releaseDistance > 0 &&
        std::any_of(sj.begin(), sj.end(), [](double s) { return !(s > 0); }))
        for (int round = 0; round < opt.maxRounds && runRound(true); ++round) {
        }
    res.minAfter = *std::min_element(sj.begin(), sj.end());
    res.belowAfter = countBelow();
    res.nodesMoved = static_cast<std::size_t>(std::count(everMoved.begin(), everMoved.end(), 1));
    res.surfaceNodesReleased = static_cast<std::size_t>(std::count(released.begin(), released.end(), 1));
    return res;
}

}  // namespace isohex::smoothing

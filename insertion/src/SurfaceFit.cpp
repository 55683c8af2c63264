#include "isohex/insertion/SurfaceFit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/VecMath.hpp"
#include "isohex/smoothing/WorstHexes.hpp"

#include "ElementGeometry.hpp"

namespace isohex::insertion {

namespace {

using namespace vec;
using Quad4 = std::array<Index, 4>;

// Sum of the hex volumes, in hex order.
double totalVolume(const HexMesh& mesh) {
    double v = 0;
    for (std::size_t h = 0; h < mesh.hexCount(); ++h) v += hexVolume(hexCoords(mesh, static_cast<Index>(h)));
    return v;
}

// The boundary quads that lie on surface `surfaceId` (all four corners on it).
std::vector<Quad4> surfaceQuads(const HexMesh& mesh, const Topology& topo, std::int32_t surfaceId) {
    auto onSurface = [&](Index v) {
        const NodeClass& c = mesh.nodeClass[static_cast<std::size_t>(v)];
        return c.kind == NodeKind::Surface && c.id == surfaceId;
    };
    std::vector<Quad4> quads;
    for (Index qi : topo.boundaryQuads) {
        const auto& q = topo.quads[static_cast<std::size_t>(qi)].nodes;
        if (onSurface(q[0]) && onSurface(q[1]) && onSurface(q[2]) && onSurface(q[3])) quads.push_back(q);
    }
    return quads;
}

// Node -> the quads at it, in quad order (a counting sort).
Csr quadsOfNodes(const std::vector<Quad4>& quads, std::size_t nodeCount) {
    Csr c;
    c.offsets.assign(nodeCount + 1, 0);
    for (const auto& q : quads)
        for (Index v : q) ++c.offsets[static_cast<std::size_t>(v) + 1];
    for (std::size_t v = 0; v < nodeCount; ++v) c.offsets[v + 1] += c.offsets[v];
    c.items.resize(static_cast<std::size_t>(c.offsets[nodeCount]));
    std::vector<Index> cursor(c.offsets.begin(), c.offsets.end() - 1);
    for (std::size_t i = 0; i < quads.size(); ++i)
        for (Index v : quads[i])
            c.items[static_cast<std::size_t>(cursor[static_cast<std::size_t>(v)]++)] = static_cast<Index>(i);
    return c;
}

// The area of the bilinear quad x0 x1 x2 x3 (from its diagonals) and its
// area-weighted mean signed distance from the triangles along its normal,
// positive where the quad is outside them (Simpson's rule, 3 x 3 points).
struct QuadGap {
    double area = 0, gap = 0;
};

QuadGap quadGap(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3, const TriangleTree& triangles) {
    static constexpr double w1[3] = {1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0};
    static constexpr double s1[3] = {0.0, 0.5, 1.0};
    const Vec3 an = detail::quadAreaVector(x0, x1, x2, x3);  // twice the area vector
    QuadGap r;
    r.area = 0.5 * norm(an);
    if (!(r.area > 0)) return r;
    const Vec3 n = (0.5 / r.area) * an;
    double g = 0;
    for (int iu = 0; iu < 3; ++iu)
        for (int iv = 0; iv < 3; ++iv) {
            const double u = s1[iu], t = s1[iv];
            const Vec3 p = (1 - u) * (1 - t) * x0 + u * (1 - t) * x1 + u * t * x2 + (1 - u) * t * x3;
            g += w1[iu] * w1[iv] * dot(p - triangles.closestPoint(p), n);
        }
    r.gap = g;
    return r;
}

// Offsets along the normals, found by Jacobi iterations: each node moves by
// minus the area-weighted mean gap of its quads at the offsets of the last
// iteration, capped at maxOffset local edge lengths.
std::vector<double> balancedOffsets(const HexMesh& mesh, const TriangleTree& triangles, const std::vector<Quad4>& quads,
                                    const Csr& quadsAt, const std::vector<Index>& nodes,
                                    const std::vector<Vec3>& normal, const std::vector<double>& length,
                                    const VolumeFitOptions& opt) {
    const std::vector<Vec3>& start = mesh.nodes;
    std::vector<double> offset(mesh.nodeCount(), 0.0);
    auto placed = [&](Index v) {
        const auto sv = static_cast<std::size_t>(v);
        return start[sv] + offset[sv] * normal[sv];
    };
    std::vector<QuadGap> gaps(quads.size());
    for (int it = 0; it < opt.iterations; ++it) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, quads.size(), 256), [&](const auto& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const auto& q = quads[i];
                gaps[i] = quadGap(placed(q[0]), placed(q[1]), placed(q[2]), placed(q[3]), triangles);
            }
        });
        for (Index v : nodes) {
            const auto sv = static_cast<std::size_t>(v);
            double num = 0, den = 0;
            for (const Index* k = quadsAt.begin(sv); k != quadsAt.end(sv); ++k) {
                const QuadGap& g = gaps[static_cast<std::size_t>(*k)];
                num += g.area * g.gap;
                den += g.area;
            }
            if (den > 0) offset[sv] -= num / den;
            const double cap = opt.maxOffset * length[sv];
            offset[sv] = std::clamp(offset[sv], -cap, cap);
        }
    }
    return offset;
}

// Applies the offsets in node order; each node keeps the largest of its
// offset, 1/2, 1/4, 1/8 of it that leaves its hexes no worse than the guard
// allows, else stays.
void applyGuarded(HexMesh& mesh, const Topology& topo, const std::vector<Index>& nodes,
                  const std::vector<Vec3>& normal, const std::vector<double>& offset, const VolumeFitOptions& opt,
                  VolumeFitResult& res) {
    using smoothing::minScaledJacobianAround;
    for (Index v : nodes) {
        const auto sv = static_cast<std::size_t>(v);
        if (offset[sv] == 0.0 || !(norm(normal[sv]) > 0)) continue;
        const double before = minScaledJacobianAround(mesh, topo, v, mesh.nodes[sv]);
        const double floor = std::min(before, opt.keepScaledJacobian);
        double t = 1.0;
        bool done = false;
        for (int k = 0; k < 4 && !done; ++k, t *= 0.5) {
            const Vec3 p = mesh.nodes[sv] + (t * offset[sv]) * normal[sv];
            if (minScaledJacobianAround(mesh, topo, v, p) >= floor) {
                mesh.nodes[sv] = p;
                res.maxOffset = std::max(res.maxOffset, std::abs(t * offset[sv]));
                ++res.nodesMoved;
                if (k > 0) ++res.nodesHeldBack;
                done = true;
            }
        }
        if (!done) ++res.nodesHeldBack;
    }
}

}  // namespace

VolumeFitResult fitSurfaceVolume(HexMesh& mesh, const TriangleTree& triangles, std::int32_t surfaceId,
                                 const VolumeFitOptions& opt) {
    VolumeFitResult res;
    const Topology topo = buildTopology(mesh);
    res.volumeBefore = totalVolume(mesh);
    const std::vector<Quad4> quads = surfaceQuads(mesh, topo, surfaceId);
    const Csr quadsAt = quadsOfNodes(quads, mesh.nodeCount());
    std::vector<Index> nodes;  // the nodes with a surface quad, in index order
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v)
        if (quadsAt.size(v) > 0) nodes.push_back(static_cast<Index>(v));
    res.nodes = nodes.size();
    if (nodes.empty()) {
        res.volumeAfter = res.volumeBefore;
        return res;
    }
    const std::vector<Vec3> normal = smoothing::surfaceNormals(mesh, topo);
    std::vector<double> length(mesh.nodeCount(), 0.0);
    for (Index v : nodes) length[static_cast<std::size_t>(v)] = smoothing::meanEdgeLengthAt(mesh, topo, v);
    const std::vector<double> offset = balancedOffsets(mesh, triangles, quads, quadsAt, nodes, normal, length, opt);
    applyGuarded(mesh, topo, nodes, normal, offset, opt, res);
    res.volumeAfter = totalVolume(mesh);
    return res;
}

}  // namespace isohex::insertion

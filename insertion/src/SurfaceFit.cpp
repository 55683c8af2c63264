#include "isohex/insertion/SurfaceFit.hpp"

#include "isohex/smoothing/WorstHexes.hpp"

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

namespace isohex::insertion {

using namespace vec;
using smoothing::meanEdgeLengthAt;
using smoothing::minScaledJacobianAround;

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
    const std::vector<Vec3> normal = smoothing::surfaceNormals(mesh, topo);
    std::vector<double> length(N, 0.0);
    for (Index v : nodes) length[static_cast<std::size_t>(v)] = meanEdgeLengthAt(mesh, topo, v);

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
    res.volumeAfter = totalVolume();
    return res;
}

}  // namespace isohex::insertion

#include "isohex/insertion/SheetInsertion.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <string>
#include <unordered_map>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/QuadSurface.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex::insertion {

namespace {

using namespace vec;

Vec3 centroid(const HexMesh& mesh, Index h) {
    Vec3 c{0, 0, 0};
    for (Index v : mesh.hexes[static_cast<std::size_t>(h)]) c = c + mesh.nodes[static_cast<std::size_t>(v)];
    return 0.125 * c;
}

// Twice the area vector of a quad (right-hand normal).
Vec3 quadNormal(const HexMesh& mesh, const std::array<Index, 4>& q) {
    const auto& x = mesh.nodes;
    return cross(x[q[2]] - x[q[0]], x[q[3]] - x[q[1]]);
}

using Clock = std::chrono::steady_clock;

}  // namespace

// ------------------------------------------------------------ geometry

std::int32_t SheetGeometry::addTree(std::shared_ptr<const TriangleTree> tree) {
    trees.push_back(std::move(tree));
    return static_cast<std::int32_t>(trees.size() - 1);
}

Vec3 SheetGeometry::project(std::int32_t surfaceId, const Vec3& x) const {
    if (surfaceId < 0 || static_cast<std::size_t>(surfaceId) >= surfaceTree.size() || surfaceTree[surfaceId] < 0)
        return x;
    return trees[static_cast<std::size_t>(surfaceTree[surfaceId])]->closestPoint(x);
}

Vec3 SheetGeometry::projectToIntersection(std::int32_t a, std::int32_t b, const Vec3& x) const {
    const TriangleTree& A = *trees[static_cast<std::size_t>(a)];
    const TriangleTree& B = *trees[static_cast<std::size_t>(b)];
    // Alternating projections converge to a point of both surfaces where they
    // cross at an angle (linearly, at the rate cos^2 of that angle).
    Vec3 p = x;
    const double tol = 1e-12 * (1.0 + norm(x));
    for (int k = 0; k < 200; ++k) {
        const Vec3 q = A.closestPoint(p);
        const Vec3 r = B.closestPoint(q);
        const double gap = norm(r - q);
        p = r;
        if (gap <= tol) break;
    }
    return p;
}

Vec3 SheetGeometry::projectToCurve(std::int32_t curveId, const Vec3& x) const {
    if (curveId < 0 || static_cast<std::size_t>(curveId) >= curves.size()) return x;
    return projectToIntersection(curves[curveId][0], curves[curveId][1], x);
}

std::size_t adoptBoundary(HexMesh& mesh, SheetGeometry& geometry, double featureAngleDegrees) {
    classifyBoundaryNodes(mesh);
    const Topology topo = buildTopology(mesh);
    // Each surface (outer boundary or interface between materials) as the
    // triangles of its quads, two per quad.
    const std::vector<SurfacePatch> patches = surfacePatches(mesh, topo);
    geometry.surfaceTree.assign(mesh.surfaces.size(), -1);
    std::vector<Index> local(mesh.nodeCount(), kNone);
    for (std::size_t s = 0; s < patches.size() && s < mesh.surfaces.size(); ++s) {
        std::vector<Vec3> vertices;
        std::vector<Index> used;
        std::vector<std::array<std::int32_t, 3>> tris;
        auto id = [&](Index v) {
            if (local[v] == kNone) {
                local[v] = static_cast<Index>(vertices.size());
                vertices.push_back(mesh.nodes[v]);
                used.push_back(v);
            }
            return local[v];
        };
        for (Index q : patches[s].quads) {
            const auto& n = topo.quads[static_cast<std::size_t>(q)].nodes;
            const Index a = id(n[0]), b = id(n[1]), c = id(n[2]), d = id(n[3]);
            tris.push_back({a, b, c});
            tris.push_back({a, c, d});
        }
        for (Index v : used) local[v] = kNone;
        if (tris.empty()) continue;
        geometry.surfaceTree[s] = geometry.addTree(
            std::make_shared<TriangleTree>(std::move(vertices), std::move(tris), surfaceName(mesh.surfaces[s])));
    }

    // Sharp boundary edges: the two boundary quads meet at more than the angle.
    const double cosLimit = std::cos(featureAngleDegrees * M_PI / 180.0);
    std::unordered_map<std::uint64_t, Vec3> firstNormal;
    std::vector<std::uint8_t> sharp(mesh.nodeCount(), 0);
    for (Index q : topo.boundaryQuads) {
        const auto& n = topo.quads[static_cast<std::size_t>(q)].nodes;
        Vec3 nq = quadNormal(mesh, n);
        const double len = norm(nq);
        if (len > 0) nq = (1.0 / len) * nq;
        for (int i = 0; i < 4; ++i) {
            const Index a = std::min(n[i], n[(i + 1) % 4]), b = std::max(n[i], n[(i + 1) % 4]);
            const std::uint64_t key = (static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b);
            auto [it, fresh] = firstNormal.emplace(key, nq);
            if (!fresh && dot(it->second, nq) < cosLimit) sharp[a] = sharp[b] = 1;
        }
    }
    std::size_t fixed = 0;
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v) {
        NodeClass& c = mesh.nodeClass[v];
        if ((sharp[v] && c.kind == NodeKind::Surface) || c.kind == NodeKind::Curve) {
            c = NodeClass{NodeKind::Fixed, -1};
            ++fixed;
        }
    }
    return fixed;
}

// ------------------------------------------------------------ insertion

InsertResult insertSheets(HexMesh& mesh, SheetGeometry& geometry, std::shared_ptr<const TriangleTree> surface,
                          const InsertOptions& opt) {
    const auto t0 = Clock::now();
    if (!surface) throw Error("insertSheets: no surface");
    mesh.checkConsistent("mesh to insert sheets into");
    const TriangleTree& S = *surface;
    InsertResult res;
    const std::size_t H = mesh.hexCount(), N = mesh.nodeCount();
    if (H == 0) throw Error("the mesh has no hexes");
    const Topology topo = buildTopology(mesh);
    if (!topo.overfullQuads.empty())
        throw Error("cannot insert sheets: the mesh has " + std::to_string(topo.overfullQuads.size()) +
                    " quads shared by more than two hexes; repair the mesh first");

    // 1. Hexes with an edge crossing a triangle (each unique edge tested once).
    const std::size_t E = topo.edges.size();
    std::vector<std::uint8_t> crossed(E, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, E, 512), [&](const auto& r) {
        for (std::size_t e = r.begin(); e != r.end(); ++e)
            crossed[e] = S.segmentCrosses(mesh.nodes[topo.edges[e][0]], mesh.nodes[topo.edges[e][1]]);
    });
    std::vector<std::uint8_t> intersected(H, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H, 1024), [&](const auto& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h)
            for (Index e : topo.hexEdges[h])
                if (crossed[static_cast<std::size_t>(e)]) intersected[h] = 1;
    });
    res.intersectedHexes = static_cast<std::size_t>(std::count(intersected.begin(), intersected.end(), 1));
    if (res.intersectedHexes == 0)
        throw Error(S.name() + ": the surface crosses no edge of the mesh; it must cut through the mesh "
                               "(check that both are in the same units and place)");

    // 2. Flood fill of the other hexes through shared faces; each group is on
    //    one side (none of its edges crosses the surface): 0 = inside, 1 = outside.
    std::vector<std::int8_t> side(H, -1);
    auto neighbour = [&](std::size_t h, int f) -> Index {
        const Quad& q = topo.quads[static_cast<std::size_t>(topo.hexQuads[h][f])];
        if (q.hex[1] == kNone) return kNone;
        return q.hex[0] == static_cast<Index>(h) ? q.hex[1] : q.hex[0];
    };
    std::vector<Index> stack;
    for (std::size_t root = 0; root < H; ++root) {
        if (intersected[root] || side[root] >= 0) continue;
        ++res.floodComponents;
        const std::int8_t s = S.inside(centroid(mesh, static_cast<Index>(root))) ? 0 : 1;
        side[root] = s;
        stack.push_back(static_cast<Index>(root));
        while (!stack.empty()) {
            const auto h = static_cast<std::size_t>(stack.back());
            stack.pop_back();
            for (int f = 0; f < 6; ++f) {
                const Index g = neighbour(h, f);
                if (g != kNone && !intersected[g] && side[g] < 0) {
                    side[g] = s;
                    stack.push_back(g);
                }
            }
        }
    }
    // 3. The intersected hexes.
    for (std::size_t h = 0; h < H; ++h) {
        if (!intersected[h]) continue;
        switch (opt.intersected) {
            case Intersected::Auto: side[h] = S.inside(centroid(mesh, static_cast<Index>(h))) ? 0 : 1; break;
            case Intersected::Side1: side[h] = 0; break;
            case Intersected::Side2: side[h] = 1; break;
        }
    }

    // Repair: move hexes across until each side's boundary is a closed
    // 2-manifold. Candidates around a bad edge or node are its hexes; the one
    // whose centroid is nearest the surface moves (each hex at most once);
    // when all have moved, an outside hex joins the inside (the inside only
    // grows from then on, so the loop ends).
    std::vector<double> dist2(H, -1.0);
    auto distanceOf = [&](Index h) {
        double& d = dist2[static_cast<std::size_t>(h)];
        if (d < 0) d = S.squaredDistance(centroid(mesh, h));
        return d;
    };
    std::vector<std::uint8_t> moved(H, 0), touched(H, 0);
    for (int round = 0;; ++round) {
        std::array<std::vector<std::array<Index, 4>>, 2> bnd;
        for (const Quad& q : topo.quads) {
            const int s0 = side[q.hex[0]];
            if (q.hex[1] == kNone) {
                bnd[s0].push_back(q.nodes);
                continue;
            }
            const int s1 = side[q.hex[1]];
            if (s0 == s1) continue;
            bnd[s0].push_back(q.nodes);
            bnd[s1].push_back({q.nodes[0], q.nodes[3], q.nodes[2], q.nodes[1]});
        }
        std::vector<std::array<Index, 2>> badEdges;
        std::vector<Index> badNodes;
        for (int s = 0; s < 2; ++s) {
            if (bnd[s].empty()) continue;
            const ManifoldCheck mc = checkManifold(bnd[s], N, true);
            badEdges.insert(badEdges.end(), mc.badEdges.begin(), mc.badEdges.end());
            badNodes.insert(badNodes.end(), mc.badNodes.begin(), mc.badNodes.end());
        }
        std::sort(badEdges.begin(), badEdges.end());
        badEdges.erase(std::unique(badEdges.begin(), badEdges.end()), badEdges.end());
        std::sort(badNodes.begin(), badNodes.end());
        badNodes.erase(std::unique(badNodes.begin(), badNodes.end()), badNodes.end());
        if (badEdges.empty() && badNodes.empty()) break;
        if (round >= opt.maxRepairRounds) {
            const Index v = badNodes.empty() ? badEdges[0][0] : badNodes[0];
            throw Error(S.name() + ": could not make both sides of the surface manifold after " +
                        std::to_string(round) + " rounds (" + std::to_string(badEdges.size()) + " edges, " +
                        std::to_string(badNodes.size()) + " nodes left, first at " +
                        at(mesh.nodes[static_cast<std::size_t>(v)]) + "); try a smaller element size");
        }
        std::fill(touched.begin(), touched.end(), 0);
        std::vector<Index> cand;
        auto fix = [&]() -> bool {
            for (Index h : cand)
                if (touched[h]) return false;  // wait for the next round
            Index best = kNone;
            for (Index h : cand)
                if (!moved[h] && (best == kNone || distanceOf(h) < distanceOf(best))) best = h;
            if (best == kNone)
                for (Index h : cand)
                    if (side[h] == 1 && (best == kNone || distanceOf(h) < distanceOf(best))) best = h;
            if (best == kNone) return false;
            side[best] = static_cast<std::int8_t>(1 - side[best]);
            moved[best] = 1;
            ++res.hexesMoved;
            for (Index h : cand) touched[h] = 1;
            return true;
        };
        for (const auto& e : badEdges) {
            cand.clear();
            std::set_intersection(topo.nodeHexes.begin(e[0]), topo.nodeHexes.end(e[0]), topo.nodeHexes.begin(e[1]),
                                  topo.nodeHexes.end(e[1]), std::back_inserter(cand));
            if (fix()) ++res.nonManifoldEdgesFixed;
        }
        for (Index v : badNodes) {
            cand.assign(topo.nodeHexes.begin(v), topo.nodeHexes.end(v));
            if (fix()) ++res.nonManifoldNodesFixed;
        }
    }
    res.side1Hexes = static_cast<std::size_t>(std::count(side.begin(), side.end(), 0));
    res.side2Hexes = H - res.side1Hexes;
    if (res.side1Hexes == 0 || res.side2Hexes == 0)
        throw Error(S.name() + ": the surface does not split the mesh (every hex is " +
                    (res.side1Hexes == 0 ? "outside" : "inside") +
                    " it); it must cut through the mesh with elements on both sides");

    // 4. The interface, seen from the inside (normals point inside -> outside).
    std::vector<std::array<Index, 4>> iface;
    std::vector<std::array<Index, 2>> ifaceHex;  // (inside hex, outside hex)
    for (const Quad& q : topo.quads) {
        if (q.hex[1] == kNone || side[q.hex[0]] == side[q.hex[1]]) continue;
        if (side[q.hex[0]] == 0) {
            iface.push_back(q.nodes);
            ifaceHex.push_back({q.hex[0], q.hex[1]});
        } else {
            iface.push_back({q.nodes[0], q.nodes[3], q.nodes[2], q.nodes[1]});
            ifaceHex.push_back({q.hex[1], q.hex[0]});
        }
    }
    res.interfaceQuads = iface.size();
    std::vector<Index> splitIndex(N, kNone);
    for (const auto& q : iface)
        for (Index v : q) splitIndex[v] = 0;
    std::vector<Index> split;
    for (std::size_t v = 0; v < N; ++v)
        if (splitIndex[v] == 0) {
            splitIndex[v] = static_cast<Index>(split.size());
            split.push_back(static_cast<Index>(v));
        }
    const std::size_t C = split.size();
    res.splitNodes = C;
    auto copyIn = [&](Index v) { return static_cast<Index>(N + 2 * static_cast<std::size_t>(splitIndex[v])); };
    auto copyOut = [&](Index v) { return static_cast<Index>(N + 2 * static_cast<std::size_t>(splitIndex[v]) + 1); };

    std::vector<Vec3> normal(C, Vec3{0, 0, 0}), bnormal(C, Vec3{0, 0, 0});
    std::vector<double> edgeSum(C, 0.0);
    std::vector<int> edgeCount(C, 0);
    for (const auto& q : iface) {
        const Vec3 n = quadNormal(mesh, q);
        for (int i = 0; i < 4; ++i) {
            const auto k = static_cast<std::size_t>(splitIndex[q[i]]);
            normal[k] = normal[k] + n;
            edgeSum[k] += norm(mesh.nodes[q[(i + 1) % 4]] - mesh.nodes[q[i]]);
            ++edgeCount[k];
        }
    }
    for (Index qi : topo.boundaryQuads) {
        const auto& q = topo.quads[static_cast<std::size_t>(qi)].nodes;
        const Vec3 n = quadNormal(mesh, q);
        for (Index v : q)
            if (splitIndex[v] != kNone) bnormal[splitIndex[v]] = bnormal[splitIndex[v]] + n;
    }

    // Where the interface reaches the mesh's boundary, the middle copy goes
    // on the curve between the old boundary surface and the new one.
    const std::int32_t newTree = geometry.addTree(surface);
    const auto newSurface = static_cast<std::int32_t>(mesh.surfaces.size());
    std::map<std::int32_t, std::int32_t> curveOf;  // old tree -> curve id
    const auto firstCurve = static_cast<std::int32_t>(geometry.curves.size());
    std::vector<NodeClass> midClass(C), copyClass(C);
    for (std::size_t k = 0; k < C; ++k) {
        const Index v = split[k];
        const NodeClass old = mesh.nodeClass[v];
        midClass[k] = NodeClass{NodeKind::Surface, newSurface};
        copyClass[k] = old;
        // A node already on a surface (the mesh's boundary, or an earlier
        // sheet) is where the two surfaces cross.
        if (old.kind == NodeKind::Surface && old.id >= 0 && static_cast<std::size_t>(old.id) < geometry.surfaceTree.size() &&
            geometry.surfaceTree[old.id] >= 0) {
            const std::int32_t t = geometry.surfaceTree[old.id];
            auto it = curveOf.find(t);
            if (it == curveOf.end()) {
                it = curveOf.emplace(t, static_cast<std::int32_t>(geometry.curves.size())).first;
                geometry.curves.push_back({t, newTree});
            }
            midClass[k] = NodeClass{NodeKind::Curve, it->second};
        } else if (old.kind == NodeKind::Curve || old.kind == NodeKind::Fixed) {
            midClass[k] = NodeClass{NodeKind::Fixed, -1};  // where three surfaces meet
        }
    }

    // Middle copies: on the curve where the interface reaches a surface the
    // mesh already has, else at the closest point of the triangles.
    std::vector<Vec3> unitNormal(C), mid(C);
    std::vector<double> spacing(C);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, C, 256), [&](const auto& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            const Index v = split[k];
            const Vec3& x = mesh.nodes[v];
            Vec3 n = normal[k];
            if (topo.nodeOnBoundary[v]) {  // keep the copies on the mesh's boundary
                const double bl = norm(bnormal[k]);
                if (bl > 0) n = n - (dot(n, bnormal[k]) / (bl * bl)) * bnormal[k];
            }
            const double nl = norm(n);
            unitNormal[k] = nl > 0 ? (1.0 / nl) * n : Vec3{0, 0, 0};
            spacing[k] = edgeSum[k] / std::max(1, edgeCount[k]);
            mid[k] = x;
            if (!opt.project) continue;
            const NodeClass old = copyClass[k];
            if (midClass[k].kind == NodeKind::Curve) {
                mid[k] = geometry.projectToCurve(midClass[k].id, x);
            } else if (midClass[k].kind == NodeKind::Fixed && old.kind == NodeKind::Curve && old.id >= 0 &&
                       static_cast<std::size_t>(old.id) < geometry.curves.size()) {
                // Where the new surface crosses a curve: the point on all three surfaces.
                const auto [a, b] = geometry.curves[static_cast<std::size_t>(old.id)];
                Vec3 p = x;
                for (int it = 0; it < 300; ++it) {
                    const Vec3 q = geometry.trees[static_cast<std::size_t>(b)]->closestPoint(
                        geometry.trees[static_cast<std::size_t>(a)]->closestPoint(S.closestPoint(p)));
                    const double step = norm(q - p);
                    p = q;
                    if (step <= 1e-12 * (1.0 + norm(p))) break;
                }
                mid[k] = p;
            } else {
                mid[k] = S.closestPoint(x);
            }
        }
    });
    // The outer copies start `offset` elements either side of the middle one
    // along the interface normal (the seed's shrinking of both sides).
    std::vector<Vec3> pos(3 * C);  // middle, inside copy, outside copy
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, C, 256), [&](const auto& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            const Index v = split[k];
            const Vec3& n = unitNormal[k];
            const double d = opt.offset * spacing[k];
            Vec3 in = mid[k] - d * n, out = mid[k] + d * n;
            if (opt.project && copyClass[k].kind == NodeKind::Surface && topo.nodeOnBoundary[v]) {
                in = geometry.project(copyClass[k].id, in);
                out = geometry.project(copyClass[k].id, out);
            } else if (opt.project && copyClass[k].kind == NodeKind::Curve) {  // copies stay on the old curve
                in = geometry.projectToCurve(copyClass[k].id, in);
                out = geometry.projectToCurve(copyClass[k].id, out);
            }
            pos[3 * k] = mid[k];
            pos[3 * k + 1] = in;
            pos[3 * k + 2] = out;
        }
    });

    // Apply: copies, each side's hexes take theirs, two new hexes per interface quad.
    std::int32_t maxMat = *std::max_element(mesh.material.begin(), mesh.material.end());
    const std::int32_t insideMat = opt.keep == Keep::Both ? (opt.insideMaterial >= 0 ? opt.insideMaterial : maxMat + 1) : -1;
    HexMesh out;
    out.surfaces = mesh.surfaces;
    out.nodes = mesh.nodes;
    out.nodeClass = mesh.nodeClass;
    out.nodes.resize(N + 2 * C);
    out.nodeClass.resize(N + 2 * C);
    for (std::size_t k = 0; k < C; ++k) {
        out.nodes[split[k]] = pos[3 * k];
        out.nodeClass[split[k]] = midClass[k];
        out.nodes[N + 2 * k] = pos[3 * k + 1];
        out.nodes[N + 2 * k + 1] = pos[3 * k + 2];
    }
    out.hexes = mesh.hexes;
    out.material = mesh.material;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H, 1024), [&](const auto& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h) {
            for (Index& v : out.hexes[h])
                if (splitIndex[v] != kNone) v = side[h] == 0 ? copyIn(v) : copyOut(v);
            if (side[h] == 0 && insideMat >= 0) out.material[h] = insideMat;
        }
    });
    std::vector<std::int8_t> newSide;  // side of the new hexes
    for (std::size_t i = 0; i < iface.size(); ++i) {
        const auto& q = iface[i];
        out.addHex({copyIn(q[0]), copyIn(q[1]), copyIn(q[2]), copyIn(q[3]), q[0], q[1], q[2], q[3]},
                   out.material[ifaceHex[i][0]]);
        newSide.push_back(0);
    }
    for (std::size_t i = 0; i < iface.size(); ++i) {
        const std::array<Index, 4> q{iface[i][0], iface[i][3], iface[i][2], iface[i][1]};
        out.addHex({copyOut(q[0]), copyOut(q[1]), copyOut(q[2]), copyOut(q[3]), q[0], q[1], q[2], q[3]},
                   out.material[ifaceHex[i][1]]);
        newSide.push_back(1);
    }
    const std::int32_t matIn = out.material[ifaceHex[0][0]], matOut = out.material[ifaceHex[0][1]];

    // Keep one side or both.
    std::vector<Index> copyNode(N + 2 * C, kNone);  // for copies: the split node
    for (std::size_t k = 0; k < C; ++k) copyNode[N + 2 * k] = copyNode[N + 2 * k + 1] = split[k];
    if (opt.keep != Keep::Both) {
        const std::int8_t drop = opt.keep == Keep::Inside ? 1 : 0;
        HexMesh kept;
        kept.surfaces = out.surfaces;
        for (std::size_t h = 0; h < out.hexCount(); ++h) {
            const std::int8_t s = h < H ? side[h] : newSide[h - H];
            if (s == drop) ++res.removedHexes;
            else kept.addHex(out.hexes[h], out.material[h]);
        }
        std::vector<Index> newId(out.nodeCount(), kNone);
        for (const Hex& hx : kept.hexes)
            for (Index v : hx) newId[v] = 0;
        std::vector<Index> keptCopyNode;
        for (std::size_t v = 0; v < out.nodeCount(); ++v)
            if (newId[v] == 0) {
                newId[v] = kept.addNode(out.nodes[v], out.nodeClass[v]);
                keptCopyNode.push_back(copyNode[v]);
            }
        for (Hex& hx : kept.hexes)
            for (Index& v : hx) v = newId[v];
        out = std::move(kept);
        copyNode = std::move(keptCopyNode);
    }
    // Copies keep the split node's boundary class only where they are on the boundary.
    const Topology after = buildTopology(out);
    for (std::size_t v = 0; v < out.nodeCount(); ++v) {
        const Index o = copyNode[v];
        if (o == kNone) continue;
        const NodeClass old = copyClass[splitIndex[o]];
        out.nodeClass[v] = after.nodeOnBoundary[v] && old.kind != NodeKind::Interior ? old : NodeClass{};
    }
    SurfaceTag tag;
    if (opt.keep == Keep::Both) {
        tag.inside = std::min(matIn, matOut);
        tag.outside = std::max(matIn, matOut);
    } else {
        tag.inside = opt.keep == Keep::Inside ? matIn : matOut;
        tag.outside = -1;
    }
    tag.name = S.name();
    out.surfaces.push_back(tag);
    geometry.surfaceTree.resize(out.surfaces.size(), -1);
    geometry.surfaceTree[static_cast<std::size_t>(newSurface)] = newTree;

    for (const NodeClass& c : out.nodeClass) {
        if (c.kind == NodeKind::Surface && c.id == newSurface) ++res.surfaceNodes;
        else if (c.kind == NodeKind::Curve && c.id >= firstCurve) ++res.curveNodes;
    }
    for (const auto& c : midClass) res.fixedNodes += c.kind == NodeKind::Fixed;
    res.sheetHexes = 2 * iface.size() - (opt.keep == Keep::Both ? 0 : iface.size());
    res.surfaceId = newSurface;
    mesh = std::move(out);
    res.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return res;
}

HexMesh regularGrid(const Vec3& lo, const Vec3& hi, double size, double margin) {
    if (!(size > 0)) throw Error("the element size must be positive");
    std::array<long long, 3> n{};
    Vec3 origin{};
    for (int i = 0; i < 3; ++i) {
        const double ext = (hi[i] - lo[i]) * (1.0 + 2.0 * margin);
        n[i] = std::max<long long>(1, static_cast<long long>(std::ceil(ext / size)));
        origin[i] = 0.5 * (lo[i] + hi[i]) - 0.5 * static_cast<double>(n[i]) * size;
    }
    const long long nodes = (n[0] + 1) * (n[1] + 1) * (n[2] + 1);
    if (nodes > std::numeric_limits<Index>::max() / 4)
        throw Error("a grid of " + std::to_string(n[0]) + " x " + std::to_string(n[1]) + " x " + std::to_string(n[2]) +
                    " elements is too large; choose a larger --size");
    HexMesh m;
    m.nodes.reserve(static_cast<std::size_t>(nodes));
    for (long long k = 0; k <= n[2]; ++k)
        for (long long j = 0; j <= n[1]; ++j)
            for (long long i = 0; i <= n[0]; ++i)
                m.addNode({origin[0] + static_cast<double>(i) * size, origin[1] + static_cast<double>(j) * size,
                           origin[2] + static_cast<double>(k) * size});
    auto id = [&](long long i, long long j, long long k) {
        return static_cast<Index>(i + (n[0] + 1) * (j + (n[1] + 1) * k));
    };
    for (long long k = 0; k < n[2]; ++k)
        for (long long j = 0; j < n[1]; ++j)
            for (long long i = 0; i < n[0]; ++i)
                m.addHex({id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k), id(i, j, k + 1),
                          id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)},
                         1);
    return m;
}

}  // namespace isohex::insertion

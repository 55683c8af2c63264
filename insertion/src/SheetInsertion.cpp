// Step 4 of the sheet insertion (SheetInsertion.hpp): split the interface
// between the two sides (Sides.cpp) into two sheets of new hexes. A sequence
// of phases over small structs: the interface, its split nodes, their
// classes, their positions, the new mesh, the side kept, the new surface.
#include "isohex/insertion/SheetInsertion.hpp"

#include <algorithm>
#include <array>
#include <map>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/VecMath.hpp"

#include "ElementGeometry.hpp"
#include "Sides.hpp"

namespace isohex::insertion {

namespace {

using namespace vec;
using detail::kInside;
using detail::kOutside;
using Quad4 = std::array<Index, 4>;

// The mesh's topology, after the checks that make an insertion possible.
Topology checkedTopology(const HexMesh& mesh) {
    mesh.checkConsistent("mesh to insert sheets into");
    if (mesh.hexCount() == 0) throw Error("the mesh has no hexes");
    Topology topo = buildTopology(mesh);
    if (!topo.overfullQuads.empty())
        throw Error("cannot insert sheets: the mesh has " + std::to_string(topo.overfullQuads.size()) +
                    " quads shared by more than two hexes; repair the mesh first");
    return topo;
}

// The quads between the two sides, seen from the inside (normals point
// inside -> outside), with the hexes on either side, in quad order.
struct Interface {
    std::vector<Quad4> quads;
    std::vector<std::array<Index, 2>> hexes;  // (inside hex, outside hex)
};

Interface findInterface(const Topology& topo, const std::vector<std::int8_t>& side) {
    Interface iface;
    for (const Quad& q : topo.quads) {
        if (q.hex[1] == kNone || side[q.hex[0]] == side[q.hex[1]]) continue;
        if (side[q.hex[0]] == kInside) {
            iface.quads.push_back(q.nodes);
            iface.hexes.push_back({q.hex[0], q.hex[1]});
        } else {
            iface.quads.push_back({q.nodes[0], q.nodes[3], q.nodes[2], q.nodes[1]});
            iface.hexes.push_back({q.hex[1], q.hex[0]});
        }
    }
    return iface;
}

// The interface's nodes in index order, each split in three: the node keeps
// the middle copy; split node k's inside and outside copies are the new
// nodes meshNodes + 2k and meshNodes + 2k + 1.
struct SplitNodes {
    std::size_t meshNodes = 0;
    std::vector<Index> nodes;  // split node k -> mesh node
    std::vector<Index> index;  // mesh node -> k, or kNone
    std::size_t size() const { return nodes.size(); }
    // The copy of split node v that the hexes of side `side` use.
    Index copy(std::int8_t side, Index v) const {
        return static_cast<Index>(meshNodes + 2 * static_cast<std::size_t>(index[v]) + (side == kInside ? 0 : 1));
    }
};

SplitNodes splitNodes(std::size_t meshNodes, const Interface& iface) {
    SplitNodes split;
    split.meshNodes = meshNodes;
    split.index.assign(meshNodes, kNone);
    for (const auto& q : iface.quads)
        for (Index v : q) split.index[v] = 0;
    for (std::size_t v = 0; v < meshNodes; ++v)
        if (split.index[v] == 0) {
            split.index[v] = static_cast<Index>(split.nodes.size());
            split.nodes.push_back(static_cast<Index>(v));
        }
    return split;
}

// Per split node: the sums of the area vectors of its interface quads and of
// its boundary quads (the normal the copies move along, kept tangent to the
// mesh's boundary), and the sum and count of its interface edge lengths.
struct InterfaceSums {
    std::vector<Vec3> normal, boundaryNormal;
    std::vector<double> edgeSum;
    std::vector<int> edgeCount;
};

InterfaceSums sumAroundSplitNodes(const HexMesh& mesh, const Topology& topo, const Interface& iface,
                                  const SplitNodes& split) {
    const std::size_t C = split.size();
    InterfaceSums sums{std::vector<Vec3>(C, Vec3{0, 0, 0}), std::vector<Vec3>(C, Vec3{0, 0, 0}),
                       std::vector<double>(C, 0.0), std::vector<int>(C, 0)};
    for (const auto& q : iface.quads) {
        const Vec3 n = detail::quadAreaVector(mesh, q);
        for (int i = 0; i < 4; ++i) {
            const auto k = static_cast<std::size_t>(split.index[q[i]]);
            sums.normal[k] = sums.normal[k] + n;
            sums.edgeSum[k] += norm(mesh.nodes[q[(i + 1) % 4]] - mesh.nodes[q[i]]);
            ++sums.edgeCount[k];
        }
    }
    for (Index qi : topo.boundaryQuads) {
        const auto& q = topo.quads[static_cast<std::size_t>(qi)].nodes;
        const Vec3 n = detail::quadAreaVector(mesh, q);
        for (Index v : q)
            if (split.index[v] != kNone)
                sums.boundaryNormal[split.index[v]] = sums.boundaryNormal[split.index[v]] + n;
    }
    return sums;
}

// Per split node: the class of its middle copy (on the new surface, on the
// curve where the new surface meets an old one, or fixed where three meet)
// and of its outer copies (the node's old class, kept only where a copy ends
// up on the boundary).
struct SplitClasses {
    std::vector<NodeClass> middle, copy;
};

// Classifies the split nodes; adds to `geometry` one curve per old surface
// tree the interface reaches, in split node order.
SplitClasses classifySplitNodes(const HexMesh& mesh, const SplitNodes& split, std::int32_t newTree,
                                std::int32_t newSurface, SheetGeometry& geometry) {
    const std::size_t C = split.size();
    SplitClasses classes{std::vector<NodeClass>(C), std::vector<NodeClass>(C)};
    std::map<std::int32_t, std::int32_t> curveOf;  // old tree -> curve id
    for (std::size_t k = 0; k < C; ++k) {
        const NodeClass old = mesh.nodeClass[split.nodes[k]];
        classes.middle[k] = NodeClass{NodeKind::Surface, newSurface};
        classes.copy[k] = old;
        // A node already on a surface (the mesh's boundary, or an earlier
        // sheet) is where the two surfaces cross.
        const bool onKnownSurface = old.kind == NodeKind::Surface && old.id >= 0 &&
                                    static_cast<std::size_t>(old.id) < geometry.surfaceTree.size() &&
                                    geometry.surfaceTree[old.id] >= 0;
        if (onKnownSurface) {
            const std::int32_t t = geometry.surfaceTree[old.id];
            auto it = curveOf.find(t);
            if (it == curveOf.end()) {
                it = curveOf.emplace(t, static_cast<std::int32_t>(geometry.curves.size())).first;
                geometry.curves.push_back({t, newTree});
            }
            classes.middle[k] = NodeClass{NodeKind::Curve, it->second};
        } else if (old.kind == NodeKind::Curve || old.kind == NodeKind::Fixed) {
            classes.middle[k] = NodeClass{NodeKind::Fixed, -1};  // where three surfaces meet
        }
    }
    return classes;
}

// Per split node: the unit normal the outer copies move along, the local
// edge length, and the middle copy's position.
struct MiddleCopies {
    std::vector<Vec3> unitNormal, position;
    std::vector<double> spacing;
};

// The interface normal at a split node, made tangent to the mesh's boundary
// where the node is on it (so the copies stay on the boundary), unit length.
Vec3 copyDirection(const InterfaceSums& sums, std::size_t k, bool onBoundary) {
    Vec3 n = sums.normal[k];
    if (onBoundary) {
        const Vec3& b = sums.boundaryNormal[k];
        const double bl = norm(b);
        if (bl > 0) n = n - (dot(n, b) / (bl * bl)) * b;
    }
    const double nl = norm(n);
    return nl > 0 ? (1.0 / nl) * n : Vec3{0, 0, 0};
}

// Middle copies: on the curve where the interface reaches a surface the mesh
// already has, at the point of three surfaces where it crosses a curve, else
// at the closest point of the triangles; where the mesh had them if
// projection is off. Parallel over split nodes, each written once.
MiddleCopies placeMiddleCopies(const HexMesh& mesh, const Topology& topo, const SheetGeometry& geometry,
                               const TriangleTree& surface, const SplitNodes& split, const InterfaceSums& sums,
                               const SplitClasses& classes, bool project) {
    const std::size_t C = split.size();
    MiddleCopies mid{std::vector<Vec3>(C), std::vector<Vec3>(C), std::vector<double>(C)};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, C, 256), [&](const auto& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            const Index v = split.nodes[k];
            const Vec3& x = mesh.nodes[v];
            mid.unitNormal[k] = copyDirection(sums, k, topo.nodeOnBoundary[v]);
            mid.spacing[k] = sums.edgeSum[k] / std::max(1, sums.edgeCount[k]);
            mid.position[k] = x;
            if (!project) continue;
            const NodeClass old = classes.copy[k];
            const NodeClass middle = classes.middle[k];
            if (middle.kind == NodeKind::Curve)
                mid.position[k] = geometry.projectToCurve(middle.id, x);
            else if (middle.kind == NodeKind::Fixed && old.kind == NodeKind::Curve && old.id >= 0 &&
                     static_cast<std::size_t>(old.id) < geometry.curves.size())
                mid.position[k] = geometry.projectToCurveCrossing(old.id, surface, x);
            else
                mid.position[k] = surface.closestPoint(x);
        }
    });
    return mid;
}

// Positions of all three copies (middle, inside, outside for split node k at
// 3k, 3k + 1, 3k + 2): the outer copies start `offset` elements either side
// of the middle one along the normal (the seed's shrinking of both sides),
// projected back onto the old surface or curve they are on.
std::vector<Vec3> placeCopies(const Topology& topo, const SheetGeometry& geometry, const SplitNodes& split,
                              const SplitClasses& classes, const MiddleCopies& mid, const InsertOptions& opt) {
    const std::size_t C = split.size();
    std::vector<Vec3> pos(3 * C);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, C, 256), [&](const auto& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
            const Index v = split.nodes[k];
            const Vec3& n = mid.unitNormal[k];
            const double d = opt.offset * mid.spacing[k];
            Vec3 in = mid.position[k] - d * n, out = mid.position[k] + d * n;
            const NodeClass& c = classes.copy[k];
            if (opt.project && c.kind == NodeKind::Surface && topo.nodeOnBoundary[v]) {
                in = geometry.project(c.id, in);
                out = geometry.project(c.id, out);
            } else if (opt.project && c.kind == NodeKind::Curve) {  // copies stay on the old curve
                in = geometry.projectToCurve(c.id, in);
                out = geometry.projectToCurve(c.id, out);
            }
            pos[3 * k] = mid.position[k];
            pos[3 * k + 1] = in;
            pos[3 * k + 2] = out;
        }
    });
    return pos;
}

// The material the inside hexes take (-1: they keep theirs).
std::int32_t insideMaterial(const HexMesh& mesh, const InsertOptions& opt) {
    const std::int32_t maxMat = *std::max_element(mesh.material.begin(), mesh.material.end());
    return opt.keep == Keep::Both ? (opt.insideMaterial >= 0 ? opt.insideMaterial : maxMat + 1) : -1;
}

// The mesh with the interface split: the old hexes (first, in their order)
// take the copies of their side, then one new hex per interface quad on the
// inside, then one per quad on the outside.
struct SplitMesh {
    HexMesh mesh;
    std::vector<std::int8_t> newSide;  // side of each new hex
    std::int32_t materialIn = 0, materialOut = 0;  // of the first interface quad's new hexes
};

SplitMesh buildSplitMesh(const HexMesh& mesh, const std::vector<std::int8_t>& side, const Interface& iface,
                         const SplitNodes& split, const SplitClasses& classes, const std::vector<Vec3>& pos,
                         std::int32_t insideMat) {
    const std::size_t N = mesh.nodeCount(), H = mesh.hexCount(), C = split.size();
    SplitMesh s;
    HexMesh& out = s.mesh;
    out.surfaces = mesh.surfaces;
    out.nodes = mesh.nodes;
    out.nodeClass = mesh.nodeClass;
    out.nodes.resize(N + 2 * C);
    out.nodeClass.resize(N + 2 * C);
    for (std::size_t k = 0; k < C; ++k) {
        out.nodes[split.nodes[k]] = pos[3 * k];
        out.nodeClass[split.nodes[k]] = classes.middle[k];
        out.nodes[N + 2 * k] = pos[3 * k + 1];
        out.nodes[N + 2 * k + 1] = pos[3 * k + 2];
    }
    out.hexes = mesh.hexes;
    out.material = mesh.material;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H, 1024), [&](const auto& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h) {
            for (Index& v : out.hexes[h])
                if (split.index[v] != kNone) v = split.copy(side[h], v);
            if (side[h] == kInside && insideMat >= 0) out.material[h] = insideMat;
        }
    });
    // The sheet hex of side s on an interface quad: its base is the quad as
    // side s sees it (reversed for the outside), on the side's copies; its
    // top is the quad's middle copies. It takes the material of its side's hex.
    for (const std::int8_t sd : {kInside, kOutside})
        for (std::size_t i = 0; i < iface.quads.size(); ++i) {
            const Quad4& f = iface.quads[i];
            const Quad4 q = sd == kInside ? f : Quad4{f[0], f[3], f[2], f[1]};
            out.addHex({split.copy(sd, q[0]), split.copy(sd, q[1]), split.copy(sd, q[2]), split.copy(sd, q[3]), q[0],
                        q[1], q[2], q[3]},
                       out.material[iface.hexes[i][sd]]);
            s.newSide.push_back(sd);
        }
    s.materialIn = out.material[iface.hexes[0][0]];
    s.materialOut = out.material[iface.hexes[0][1]];
    return s;
}

// Per node of the split mesh: for an outer copy, the node it was split from; else kNone.
std::vector<Index> copyOrigins(const SplitNodes& split) {
    const std::size_t N = split.meshNodes, C = split.size();
    std::vector<Index> origin(N + 2 * C, kNone);
    for (std::size_t k = 0; k < C; ++k) origin[N + 2 * k] = origin[N + 2 * k + 1] = split.nodes[k];
    return origin;
}

// Drops the hexes of side `drop` (old hexes by `side`, new ones by
// s.newSide) and the nodes no kept hex uses, renumbering the rest in order;
// `origin` follows the renumbering. Returns the number of hexes dropped.
std::size_t dropSide(SplitMesh& s, const std::vector<std::int8_t>& side, std::int8_t drop, std::vector<Index>& origin) {
    const HexMesh& out = s.mesh;
    const std::size_t H = side.size();
    std::size_t removed = 0;
    HexMesh kept;
    kept.surfaces = out.surfaces;
    for (std::size_t h = 0; h < out.hexCount(); ++h) {
        const std::int8_t hs = h < H ? side[h] : s.newSide[h - H];
        if (hs == drop) ++removed;
        else kept.addHex(out.hexes[h], out.material[h]);
    }
    std::vector<Index> newId(out.nodeCount(), kNone);
    for (const Hex& hx : kept.hexes)
        for (Index v : hx) newId[v] = 0;
    std::vector<Index> keptOrigin;
    for (std::size_t v = 0; v < out.nodeCount(); ++v)
        if (newId[v] == 0) {
            newId[v] = kept.addNode(out.nodes[v], out.nodeClass[v]);
            keptOrigin.push_back(origin[v]);
        }
    for (Hex& hx : kept.hexes)
        for (Index& v : hx) v = newId[v];
    s.mesh = std::move(kept);
    origin = std::move(keptOrigin);
    return removed;
}

// Outer copies keep the split node's old class only where they are on the
// mesh's boundary; inside the mesh they are interior.
void classifyCopies(HexMesh& out, const std::vector<Index>& origin, const SplitNodes& split,
                    const SplitClasses& classes) {
    const Topology after = buildTopology(out);
    for (std::size_t v = 0; v < out.nodeCount(); ++v) {
        const Index o = origin[v];
        if (o == kNone) continue;
        const NodeClass old = classes.copy[split.index[o]];
        out.nodeClass[v] = after.nodeOnBoundary[v] && old.kind != NodeKind::Interior ? old : NodeClass{};
    }
}

// The new surface's tag: the interface between the two materials, or the
// boundary of the side kept.
SurfaceTag newSurfaceTag(Keep keep, std::int32_t matIn, std::int32_t matOut, const std::string& name) {
    SurfaceTag tag;
    if (keep == Keep::Both) {
        tag.inside = std::min(matIn, matOut);
        tag.outside = std::max(matIn, matOut);
    } else {
        tag.inside = keep == Keep::Inside ? matIn : matOut;
        tag.outside = -1;
    }
    tag.name = name;
    return tag;
}

// The node counts of the result: nodes on the new surface and its curves,
// and middle copies fixed where three surfaces meet.
void countNodes(const HexMesh& out, std::int32_t newSurface, std::int32_t firstCurve, const SplitClasses& classes,
                InsertResult& res) {
    for (const NodeClass& c : out.nodeClass) {
        if (c.kind == NodeKind::Surface && c.id == newSurface) ++res.surfaceNodes;
        else if (c.kind == NodeKind::Curve && c.id >= firstCurve) ++res.curveNodes;
    }
    for (const auto& c : classes.middle) res.fixedNodes += c.kind == NodeKind::Fixed;
}

}  // namespace

InsertResult insertSheets(HexMesh& mesh, SheetGeometry& geometry, std::shared_ptr<const TriangleTree> surface,
                          const InsertOptions& opt) {
    const Stopwatch watch;
    if (!surface) throw Error("insertSheets: no surface");
    const TriangleTree& S = *surface;
    const Topology topo = checkedTopology(mesh);
    InsertResult res;
    // Steps 1-3 (Sides.cpp); every error is thrown there, before anything changes.
    const std::vector<std::int8_t> side = detail::assignSides(mesh, topo, S, opt, res);

    const Interface iface = findInterface(topo, side);
    res.interfaceQuads = iface.quads.size();
    const SplitNodes split = splitNodes(mesh.nodeCount(), iface);
    res.splitNodes = split.size();
    const InterfaceSums sums = sumAroundSplitNodes(mesh, topo, iface, split);

    const std::int32_t newTree = geometry.addTree(surface);
    const auto newSurface = static_cast<std::int32_t>(mesh.surfaces.size());
    const auto firstCurve = static_cast<std::int32_t>(geometry.curves.size());
    const SplitClasses classes = classifySplitNodes(mesh, split, newTree, newSurface, geometry);
    const MiddleCopies mid = placeMiddleCopies(mesh, topo, geometry, S, split, sums, classes, opt.project);
    const std::vector<Vec3> pos = placeCopies(topo, geometry, split, classes, mid, opt);

    SplitMesh out = buildSplitMesh(mesh, side, iface, split, classes, pos, insideMaterial(mesh, opt));
    std::vector<Index> origin = copyOrigins(split);
    if (opt.keep != Keep::Both)
        res.removedHexes = dropSide(out, side, opt.keep == Keep::Inside ? kOutside : kInside, origin);
    classifyCopies(out.mesh, origin, split, classes);
    out.mesh.surfaces.push_back(newSurfaceTag(opt.keep, out.materialIn, out.materialOut, S.name()));
    geometry.surfaceTree.resize(out.mesh.surfaces.size(), -1);
    geometry.surfaceTree[static_cast<std::size_t>(newSurface)] = newTree;

    countNodes(out.mesh, newSurface, firstCurve, classes, res);
    res.sheetHexes = 2 * iface.quads.size() - (opt.keep == Keep::Both ? 0 : iface.quads.size());
    res.surfaceId = newSurface;
    mesh = std::move(out.mesh);
    res.seconds = watch.seconds();
    return res;
}

}  // namespace isohex::insertion

// Steps 1-3 of the sheet insertion: the hexes the surface cuts, the sides of
// the others by flood fill, the cut hexes' side, and the repair that makes
// each side's boundary a closed 2-manifold (so that step 4 can split it).
#include "Sides.hpp"

#include <algorithm>
#include <array>
#include <iterator>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/QuadSurface.hpp"
#include "isohex/core/VecMath.hpp"

#include "ElementGeometry.hpp"

namespace isohex::insertion::detail {

namespace {

using Quad4 = std::array<Index, 4>;

template <class T>
void sortUnique(std::vector<T>& v) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
}

std::int8_t sideOf(const TriangleTree& surface, const HexMesh& mesh, Index h) {
    return surface.inside(centroid(mesh, h)) ? kInside : kOutside;
}

// Step 1: hexes with an edge crossing a triangle (each unique edge tested
// once, in parallel; the result does not depend on the thread count).
std::vector<std::uint8_t> findIntersected(const HexMesh& mesh, const Topology& topo, const TriangleTree& surface) {
    const std::size_t E = topo.edges.size(), H = mesh.hexCount();
    std::vector<std::uint8_t> crossed(E, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, E, 512), [&](const auto& r) {
        for (std::size_t e = r.begin(); e != r.end(); ++e)
            crossed[e] = surface.segmentCrosses(mesh.nodes[topo.edges[e][0]], mesh.nodes[topo.edges[e][1]]);
    });
    std::vector<std::uint8_t> intersected(H, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H, 1024), [&](const auto& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h)
            for (Index e : topo.hexEdges[h])
                if (crossed[static_cast<std::size_t>(e)]) intersected[h] = 1;
    });
    return intersected;
}

// The hex across local face f of hex h, or kNone on the boundary.
Index faceNeighbour(const Topology& topo, std::size_t h, int f) {
    const Quad& q = topo.quads[static_cast<std::size_t>(topo.hexQuads[h][f])];
    if (q.hex[1] == kNone) return kNone;
    return q.hex[0] == static_cast<Index>(h) ? q.hex[1] : q.hex[0];
}

// Step 2: the hexes not cut, flood-filled through shared faces; no edge of a
// group crosses the surface, so the whole group is on the side of its first
// hex's centroid. Returns the number of groups.
std::size_t floodSides(const HexMesh& mesh, const Topology& topo, const TriangleTree& surface,
                       const std::vector<std::uint8_t>& intersected, std::vector<std::int8_t>& side) {
    std::size_t components = 0;
    std::vector<Index> stack;
    for (std::size_t root = 0; root < mesh.hexCount(); ++root) {
        if (intersected[root] || side[root] >= 0) continue;
        ++components;
        const std::int8_t s = sideOf(surface, mesh, static_cast<Index>(root));
        side[root] = s;
        stack.push_back(static_cast<Index>(root));
        while (!stack.empty()) {
            const auto h = static_cast<std::size_t>(stack.back());
            stack.pop_back();
            for (int f = 0; f < 6; ++f) {
                const Index g = faceNeighbour(topo, h, f);
                if (g != kNone && !intersected[g] && side[g] < 0) {
                    side[g] = s;
                    stack.push_back(g);
                }
            }
        }
    }
    return components;
}

// Step 3a: the cut hexes join the side the options say (auto: their centroid's).
void placeIntersected(const HexMesh& mesh, const TriangleTree& surface, const std::vector<std::uint8_t>& intersected,
                      Intersected mode, std::vector<std::int8_t>& side) {
    for (std::size_t h = 0; h < mesh.hexCount(); ++h) {
        if (!intersected[h]) continue;
        switch (mode) {
            case Intersected::Auto: side[h] = sideOf(surface, mesh, static_cast<Index>(h)); break;
            case Intersected::Side1: side[h] = kInside; break;
            case Intersected::Side2: side[h] = kOutside; break;
        }
    }
}

// The edges and nodes where a side's boundary is not a closed 2-manifold.
struct NonManifold {
    std::vector<std::array<Index, 2>> edges;
    std::vector<Index> nodes;
    bool empty() const { return edges.empty() && nodes.empty(); }
};

// Step 3b: moves hexes across until each side's boundary is a closed
// 2-manifold. Candidates around a bad edge or node are its hexes; the one
// whose centroid is nearest the surface moves (each hex at most once); when
// all have moved, an outside hex joins the inside (the inside only grows from
// then on, so the loop ends). A hex next to one moved this round waits for
// the next round.
class SideRepair {
public:
    SideRepair(const HexMesh& mesh, const Topology& topo, const TriangleTree& surface, std::vector<std::int8_t>& side)
        : mesh_(mesh), topo_(topo), surface_(surface), side_(side), distance2_(mesh.hexCount(), -1.0),
          moved_(mesh.hexCount(), 0), touched_(mesh.hexCount(), 0) {}

    void run(int maxRounds, InsertResult& result) {
        for (int round = 0;; ++round) {
            const NonManifold bad = findNonManifold();
            if (bad.empty()) return;
            if (round >= maxRounds) throwUnrepaired(bad, round);
            repairRound(bad, result);
        }
    }

private:
    // Each side's boundary quads, oriented out of that side: the mesh's
    // boundary quads and the quads between the sides.
    std::array<std::vector<Quad4>, 2> sideBoundaries() const {
        std::array<std::vector<Quad4>, 2> bnd;
        for (const Quad& q : topo_.quads) {
            const int s0 = side_[q.hex[0]];
            if (q.hex[1] == kNone) {
                bnd[s0].push_back(q.nodes);
                continue;
            }
            const int s1 = side_[q.hex[1]];
            if (s0 == s1) continue;
            bnd[s0].push_back(q.nodes);
            bnd[s1].push_back({q.nodes[0], q.nodes[3], q.nodes[2], q.nodes[1]});
        }
        return bnd;
    }

    // The bad edges and nodes of both sides, sorted and without repeats.
    NonManifold findNonManifold() const {
        const std::array<std::vector<Quad4>, 2> bnd = sideBoundaries();
        NonManifold bad;
        for (int s = 0; s < 2; ++s) {
            if (bnd[s].empty()) continue;
            const ManifoldCheck mc = checkManifold(bnd[s], mesh_.nodeCount(), true);
            bad.edges.insert(bad.edges.end(), mc.badEdges.begin(), mc.badEdges.end());
            bad.nodes.insert(bad.nodes.end(), mc.badNodes.begin(), mc.badNodes.end());
        }
        sortUnique(bad.edges);
        sortUnique(bad.nodes);
        return bad;
    }

    [[noreturn]] void throwUnrepaired(const NonManifold& bad, int rounds) const {
        const Index v = bad.nodes.empty() ? bad.edges[0][0] : bad.nodes[0];
        throw Error(surface_.name() + ": could not make both sides of the surface manifold after " +
                    std::to_string(rounds) + " rounds (" + std::to_string(bad.edges.size()) + " edges, " +
                    std::to_string(bad.nodes.size()) + " nodes left, first at " +
                    vec::at(mesh_.nodes[static_cast<std::size_t>(v)]) + "); try a smaller element size");
    }

    // One round: a move at every bad edge (the hexes around both ends), then
    // at every bad node, unless a neighbour already moved this round.
    void repairRound(const NonManifold& bad, InsertResult& result) {
        std::fill(touched_.begin(), touched_.end(), 0);
        std::vector<Index> candidates;
        for (const auto& e : bad.edges) {
            candidates.clear();
            std::set_intersection(topo_.nodeHexes.begin(e[0]), topo_.nodeHexes.end(e[0]), topo_.nodeHexes.begin(e[1]),
                                  topo_.nodeHexes.end(e[1]), std::back_inserter(candidates));
            if (moveOne(candidates, result)) ++result.nonManifoldEdgesFixed;
        }
        for (Index v : bad.nodes) {
            candidates.assign(topo_.nodeHexes.begin(v), topo_.nodeHexes.end(v));
            if (moveOne(candidates, result)) ++result.nonManifoldNodesFixed;
        }
    }

    // Moves the candidate nearest the surface that has not moved yet (else
    // the outside candidate nearest it) to the other side.
    bool moveOne(const std::vector<Index>& candidates, InsertResult& result) {
        for (Index h : candidates)
            if (touched_[h]) return false;  // wait for the next round
        Index best = kNone;
        for (Index h : candidates)
            if (!moved_[h] && (best == kNone || distance2(h) < distance2(best))) best = h;
        if (best == kNone)
            for (Index h : candidates)
                if (side_[h] == kOutside && (best == kNone || distance2(h) < distance2(best))) best = h;
        if (best == kNone) return false;
        side_[best] = static_cast<std::int8_t>(1 - side_[best]);
        moved_[best] = 1;
        ++result.hexesMoved;
        for (Index h : candidates) touched_[h] = 1;
        return true;
    }

    // Squared distance of a hex's centroid from the surface, computed once.
    double distance2(Index h) {
        double& d = distance2_[static_cast<std::size_t>(h)];
        if (d < 0) d = surface_.squaredDistance(centroid(mesh_, h));
        return d;
    }

    const HexMesh& mesh_;
    const Topology& topo_;
    const TriangleTree& surface_;
    std::vector<std::int8_t>& side_;
    std::vector<double> distance2_;
    std::vector<std::uint8_t> moved_, touched_;
};

}  // namespace

std::vector<std::int8_t> assignSides(const HexMesh& mesh, const Topology& topo, const TriangleTree& surface,
                                     const InsertOptions& options, InsertResult& result) {
    const std::size_t H = mesh.hexCount();
    const std::vector<std::uint8_t> intersected = findIntersected(mesh, topo, surface);
    result.intersectedHexes = static_cast<std::size_t>(std::count(intersected.begin(), intersected.end(), 1));
    if (result.intersectedHexes == 0)
        throw Error(surface.name() + ": the surface crosses no edge of the mesh; it must cut through the mesh "
                                     "(check that both are in the same units and place)");
    std::vector<std::int8_t> side(H, kNoSide);
    result.floodComponents = floodSides(mesh, topo, surface, intersected, side);
    placeIntersected(mesh, surface, intersected, options.intersected, side);
    SideRepair(mesh, topo, surface, side).run(options.maxRepairRounds, result);

    result.side1Hexes = static_cast<std::size_t>(std::count(side.begin(), side.end(), kInside));
    result.side2Hexes = H - result.side1Hexes;
    if (result.side1Hexes == 0 || result.side2Hexes == 0)
        throw Error(surface.name() + ": the surface does not split the mesh (every hex is " +
                    (result.side1Hexes == 0 ? "outside" : "inside") +
                    " it); it must cut through the mesh with elements on both sides");
    return side;
}

}  // namespace isohex::insertion::detail

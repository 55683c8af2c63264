// The smoother's set-up: how each node may move, the colouring, per-node
// surface quads and curve neighbours, reference lengths, and the thinning of
// curve bands before any of it.
#include <cmath>
#include <limits>
#include <string>

#include "Smoother.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex::smoothing::detail {
namespace {

// node -> the quads of a surface (quadSurface >= 0) that hold it, in quad order.
Csr surfaceQuadsAtNodes(const Topology& topo, const std::vector<std::int32_t>& quadSurface, std::size_t N) {
    Csr c;
    c.offsets.assign(N + 1, 0);
    for (std::size_t q = 0; q < topo.quads.size(); ++q)
        if (quadSurface[q] >= 0)
            for (Index v : topo.quads[q].nodes) ++c.offsets[static_cast<std::size_t>(v) + 1];
    for (std::size_t v = 0; v < N; ++v) c.offsets[v + 1] += c.offsets[v];
    c.items.resize(static_cast<std::size_t>(c.offsets[N]));
    std::vector<Index> cursor(c.offsets.begin(), c.offsets.end() - 1);
    for (std::size_t q = 0; q < topo.quads.size(); ++q)
        if (quadSurface[q] >= 0)
            for (Index v : topo.quads[q].nodes)
                c.items[static_cast<std::size_t>(cursor[static_cast<std::size_t>(v)]++)] = static_cast<Index>(q);
    return c;
}

}  // namespace

void Smoother::setUp() {
    mesh_.checkConsistent("mesh to smooth");
    const std::size_t N = mesh_.nodeCount();
    if (&topo_ == &ownTopology_) ownTopology_ = buildTopology(mesh_, TopologyParts::SurfaceMoves);
    else requireTopologyOf(mesh_, topo_, "smoothing");
    {
        const std::vector<std::int32_t> quadSurface = quadSurfaces();
        if (!quadSurface.empty() && projector_->hasCurves()) thinCurveBands(quadSurface);
        const bool anySurface = assignModes();
        colourMovable();
        if (anySurface) buildSurfaceQuads(quadSurface);
    }
    buildCurveNeighbours();
    measureReferenceLengths();
    // The phases read node-to-hex rows only (and surfaceQuadNodes_): a
    // topology built here (its surface quads and edges, TopologyParts::
    // SurfaceMoves) keeps nothing else and lets the rest go before the
    // per-node state below is allocated.
    if (&topo_ == &ownTopology_) {
        Topology kept;
        kept.nodeHexes = std::move(ownTopology_.nodeHexes);
        ownTopology_ = std::move(kept);
    }
    buffers_ = std::make_unique<tbb::enumerable_thread_specific<std::vector<CornerTerm>>>(
        [n = maxTerms_] { return std::vector<CornerTerm>(n); });
    everMoved_.assign(N, 0);
    nodeMoved_.assign(N, 0);
    touched_.assign(N, 0);
    start_ = mesh_.nodes;
}

std::vector<std::int32_t> Smoother::quadSurfaces() const {
    std::vector<std::int32_t> quadSurface;
    if (!projector_ || opt_.fixBoundary) return quadSurface;
    quadSurface.assign(topo_.quads.size(), -1);
    for (const SurfacePatch& p : surfacePatches(mesh_, topo_)) {
        std::int32_t id = -1;
        for (std::size_t s = 0; s < mesh_.surfaces.size(); ++s)
            if (mesh_.surfaces[s].inside == p.tag.inside && mesh_.surfaces[s].outside == p.tag.outside)
                id = static_cast<std::int32_t>(s);
        for (Index q : p.quads) quadSurface[static_cast<std::size_t>(q)] = id;
    }
    return quadSurface;
}

bool Smoother::assignModes() {
    const std::size_t N = mesh_.nodeCount();
    mode_.assign(N, Mode::Frozen);
    bool anySurface = false;
    for (std::size_t v = 0; v < N; ++v) {
        if (topo_.nodeHexes.size(v) == 0) continue;
        const NodeClass& c = mesh_.nodeClass[v];
        switch (c.kind) {
            case NodeKind::Interior:
                // An unclassified boundary node would let the mesh shrink: keep it.
                if (!topo_.nodeOnBoundary[v]) mode_[v] = Mode::Interior;
                break;
            case NodeKind::Surface:
                if (c.id < 0 || static_cast<std::size_t>(c.id) >= mesh_.surfaces.size())
                    throw Error("smoothing: node " + std::to_string(v) + " is on surface " + std::to_string(c.id) +
                                " but the mesh has " + std::to_string(mesh_.surfaces.size()) +
                                " surfaces; classify the boundary (classifyBoundaryNodes) before smoothing");
                if (!opt_.fixBoundary && projector_) {
                    mode_[v] = Mode::Surface;
                    anySurface = true;
                }
                break;
            case NodeKind::Curve:
                if (!opt_.fixBoundary && projector_ &&
                    (projector_->hasCurves() || (opt_.untangle && opt_.releaseSurfaceToUntangle)))
                    mode_[v] = Mode::Curve;
                break;
            default: break;
        }
    }
    // A hex that repeats a node is degenerate; none of its nodes can be moved
    // with the one-node-per-corner-slot model, so they stay put (and the hex is
    // reported if it stays inverted).
    for (const Hex& h : mesh_.hexes)
        for (int i = 0; i < 8; ++i)
            for (int j = i + 1; j < 8; ++j)
                if (h[i] == h[j])
                    for (Index u : h) mode_[static_cast<std::size_t>(u)] = Mode::Frozen;
    return anySurface;
}

void Smoother::colourMovable() {
    const std::size_t N = mesh_.nodeCount();
    std::vector<std::uint8_t> movable(N);
    for (std::size_t v = 0; v < N; ++v) {
        movable[v] = mode_[v] != Mode::Frozen;
        if (movable[v]) {
            ++result_.movableNodes;
            maxTerms_ = std::max(maxTerms_, termsPerHex * topo_.nodeHexes.size(v));
        }
    }
    colouring_ = colourNodes(mesh_, topo_.nodeHexes, movable);
    result_.colours = static_cast<int>(colouring_.classes.size());
}

// Several surfaces may share a material pair (a block's faces and a cut both
// bound material 1): quads are matched to a node by the pair.
void Smoother::buildSurfaceQuads(const std::vector<std::int32_t>& quadSurface) {
    const std::size_t N = mesh_.nodeCount();
    auto& c = nodeSurfaceQuads_;
    c.offsets.assign(N + 1, 0);
    auto uses = [&](std::size_t q, Index v) {
        if (mode_[static_cast<std::size_t>(v)] != Mode::Surface || quadSurface[q] < 0) return false;
        const SurfaceTag& a = mesh_.surfaces[static_cast<std::size_t>(quadSurface[q])];
        const SurfaceTag& b = mesh_.surfaces[static_cast<std::size_t>(mesh_.nodeClass[static_cast<std::size_t>(v)].id)];
        return a.inside == b.inside && a.outside == b.outside;
    };
    for (std::size_t q = 0; q < topo_.quads.size(); ++q)
        for (Index v : topo_.quads[q].nodes)
            if (uses(q, v)) ++c.offsets[static_cast<std::size_t>(v) + 1];
    for (std::size_t v = 0; v < N; ++v) c.offsets[v + 1] += c.offsets[v];
    c.items.resize(static_cast<std::size_t>(c.offsets[N]));
    std::vector<Index> cursor(c.offsets.begin(), c.offsets.end() - 1);
    // rows name slots of surfaceQuadNodes_: the quads used, in quad order
    std::vector<Index> slot(topo_.quads.size(), kNone);
    surfaceQuadNodes_.clear();
    for (std::size_t q = 0; q < topo_.quads.size(); ++q)
        for (Index v : topo_.quads[q].nodes)
            if (uses(q, v)) {
                if (slot[q] == kNone) {
                    slot[q] = static_cast<Index>(surfaceQuadNodes_.size());
                    surfaceQuadNodes_.push_back(topo_.quads[q].nodes);
                }
                c.items[static_cast<std::size_t>(cursor[static_cast<std::size_t>(v)]++)] = slot[q];
            }
}

// Curve neighbours: edges joining two curve nodes of the same curve; at the
// end of a chain (fewer than two), also fixed boundary nodes joined by an
// edge (the vertex where the curve ends).
void Smoother::buildCurveNeighbours() {
    const std::size_t N = mesh_.nodeCount();
    auto& c = nodeCurveNeighbours_;
    c.offsets.assign(N + 1, 0);
    auto sameCurve = [&](std::size_t a, std::size_t b) {
        return mode_[a] == Mode::Curve && mode_[b] == Mode::Curve && mesh_.nodeClass[a].id == mesh_.nodeClass[b].id;
    };
    std::vector<std::uint8_t> chainEnd(N, 0);
    {
        std::vector<std::uint8_t> count(N, 0);
        for (const auto& e : topo_.edges)
            if (sameCurve(static_cast<std::size_t>(e[0]), static_cast<std::size_t>(e[1])))
                for (Index u : e) count[static_cast<std::size_t>(u)] = static_cast<std::uint8_t>(std::min(2, count[static_cast<std::size_t>(u)] + 1));
        for (std::size_t v = 0; v < N; ++v) chainEnd[v] = mode_[v] == Mode::Curve && count[v] < 2;
    }
    auto endsAt = [&](std::size_t a, std::size_t b) {
        return chainEnd[a] && mesh_.nodeClass[b].kind == NodeKind::Fixed && topo_.nodeOnBoundary[b];
    };
    auto joins = [&](const std::array<Index, 2>& e) {
        const auto a = static_cast<std::size_t>(e[0]), b = static_cast<std::size_t>(e[1]);
        return sameCurve(a, b) || endsAt(a, b) || endsAt(b, a);
    };
    // Only curve nodes get rows (a fixed end node never moves).
    auto isCurve = [&](Index v) { return mode_[static_cast<std::size_t>(v)] == Mode::Curve; };
    for (const auto& e : topo_.edges)
        if (joins(e)) {
            if (isCurve(e[0])) ++c.offsets[static_cast<std::size_t>(e[0]) + 1];
            if (isCurve(e[1])) ++c.offsets[static_cast<std::size_t>(e[1]) + 1];
        }
    for (std::size_t v = 0; v < N; ++v) c.offsets[v + 1] += c.offsets[v];
    c.items.resize(static_cast<std::size_t>(c.offsets[N]));
    std::vector<Index> cursor(c.offsets.begin(), c.offsets.end() - 1);
    for (const auto& e : topo_.edges)
        if (joins(e)) {
            if (isCurve(e[0])) c.items[static_cast<std::size_t>(cursor[static_cast<std::size_t>(e[0])]++)] = e[1];
            if (isCurve(e[1])) c.items[static_cast<std::size_t>(cursor[static_cast<std::size_t>(e[1])]++)] = e[0];
        }
}

void Smoother::measureReferenceLengths() {
    const std::size_t N = mesh_.nodeCount();
    std::vector<double> sum(N, 0.0);
    std::vector<int> count(N, 0);
    for (const auto& e : topo_.edges) {
        const auto a = static_cast<std::size_t>(e[0]), b = static_cast<std::size_t>(e[1]);
        const double l = vec::norm(vec::operator-(mesh_.nodes[a], mesh_.nodes[b]));
        sum[a] += l;
        sum[b] += l;
        ++count[a];
        ++count[b];
    }
    refLength_.resize(N);
    for (std::size_t v = 0; v < N; ++v)
        refLength_[v] = count[v] ? sum[v] / count[v] : std::numeric_limits<double>::infinity();
}

// Curve bands. Extraction marks every cell where three materials meet, and
// where a junction runs diagonally to the grid those cells form a band two
// wide instead of a chain: a surface quad then has three or four nodes of one
// curve. Once they are all on the curve (a line) that quad is flat, with an
// angle near 180 degrees or no area at all, and the hexes on it cannot be
// untangled (label atlases meshed at a few voxels per element). Before smoothing, in each such quad the
// node farthest from the curve is made a surface node until at most two of
// the curve's nodes are left (on a tie, one between two others of the curve:
// the corner where the chain turns inside the quad). It goes on the nearest
// of the surfaces its quads belong to.
void Smoother::thinCurveBands(const std::vector<std::int32_t>& quadSurface) {
    const std::size_t N = mesh_.nodeCount();
    auto curveOf = [&](Index v) {
        const NodeClass& c = mesh_.nodeClass[static_cast<std::size_t>(v)];
        return c.kind == NodeKind::Curve ? c.id : -1;
    };
    auto distance = [](const Vec3& x, const Vec3& y) {
        const double e = std::hypot(y[0] - x[0], y[1] - x[1], y[2] - x[2]);
        return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
    };
    std::vector<double> offCurve(N, -1.0);  // distance to its curve, computed when first needed
    const Csr quadsAt = surfaceQuadsAtNodes(topo_, quadSurface, N);
    std::vector<std::int32_t> surfaces;
    for (std::size_t q = 0; q < topo_.quads.size(); ++q) {
        if (quadSurface[q] < 0) continue;
        const auto& n = topo_.quads[q].nodes;
        for (;;) {
            int pick = -1, pickBetween = -1;
            double pickOff = -1;  // a failed projection counts as infinitely far
            for (int i = 0; i < 4; ++i) {
                const std::int32_t c = curveOf(n[i]);
                if (c < 0) continue;
                int same = 0, between = 0;
                for (int j = 0; j < 4; ++j)
                    if (curveOf(n[j]) == c) {
                        ++same;
                        between += j == (i + 1) % 4 || j == (i + 3) % 4;
                    }
                if (same < 3) continue;
                const auto sv = static_cast<std::size_t>(n[i]);
                if (offCurve[sv] < 0) offCurve[sv] = distance(mesh_.nodes[sv], projector_->projectToCurve(c, mesh_.nodes[sv]));
                if (offCurve[sv] > pickOff || (offCurve[sv] == pickOff && between > pickBetween)) {
                    pick = i;
                    pickBetween = between;
                    pickOff = offCurve[sv];
                }
            }
            if (pick < 0) break;
            const Index v = n[pick];
            const Vec3 x = mesh_.nodes[static_cast<std::size_t>(v)];
            surfaces.clear();  // of the quads around it
            for (const Index* f = quadsAt.begin(static_cast<std::size_t>(v)); f != quadsAt.end(static_cast<std::size_t>(v)); ++f) {
                const std::int32_t s = quadSurface[static_cast<std::size_t>(*f)];
                if (std::find(surfaces.begin(), surfaces.end(), s) == surfaces.end()) surfaces.push_back(s);
            }
            std::sort(surfaces.begin(), surfaces.end());
            std::int32_t best = -1;
            double bestOff = std::numeric_limits<double>::infinity();
            for (const std::int32_t s : surfaces) {
                const double e = distance(x, projector_->project(s, x));
                if (e < bestOff) {
                    bestOff = e;
                    best = s;
                }
            }
            // No surface to stay on (every projection failed): keep it where it is.
            mesh_.nodeClass[static_cast<std::size_t>(v)] =
                best >= 0 ? NodeClass{NodeKind::Surface, best} : NodeClass{NodeKind::Fixed, -1};
            ++result_.curveNodesDemoted;
        }
    }
}

}  // namespace isohex::smoothing::detail

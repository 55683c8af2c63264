// Node placement of the adaptive mesher (AdaptiveSurface.hpp): uniform nodes
// where every leaf around is level 0, surface nets elsewhere.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <tbb/parallel_for.h>

#include "AdaptiveSurfaceParts.hpp"
#include "SegmentRoot.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"

namespace isohex::octree {

namespace {

constexpr std::int64_t kS = kKeySteps;

Vec3 lerp(const Vec3& a, const Vec3& b, double t) {
    return {a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])};
}

// Where f (material m's function) changes sign on a..b (rootOnSegment);
// false when it does not.
bool crossing(const Domain& d, std::int32_t m, const Vec3& a, const Vec3& b, Vec3& out) {
    const double f0 = d.value(m, a), f1 = d.value(m, b);
    if (!std::isfinite(f0) || !std::isfinite(f1) || (f0 < 0) == (f1 < 0)) return false;
    out = lerp(a, b, rootOnSegment([&](const Vec3& x) { return d.value(m, x); }, a, b, f0, f1));
    return true;
}

// Newton steps onto material m's zero set, each at most `maxStep` long.
void newton(const Domain& d, std::int32_t m, Vec3& x, double maxStep) {
    for (int it = 0; it < 6; ++it) {
        Vec3 g;
        const double f = d.value(m, x, &g);
        const double gg = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
        if (!std::isfinite(f) || !(gg > 1e-30)) return;
        double s = f / gg;
        const double len = std::abs(s) * std::sqrt(gg);
        if (len > maxStep) s *= maxStep / len;
        for (int c = 0; c < 3; ++c) x[c] -= s * g[c];
        if (len < 1e-4 * maxStep) return;
    }
}

Vec3 centroid(const PlacedMesh& p, Index h) {
    Vec3 c{0, 0, 0};
    for (Index n : p.a.mesh.hexes[static_cast<std::size_t>(h)])
        for (int k = 0; k < 3; ++k) c[k] += p.lattice[static_cast<std::size_t>(n)][k] / 8;
    return c;
}

// The boundary and interface quads with their surfaces.
void collectQuads(PlacedMesh& p) {
    const HexMesh& m = p.a.mesh;
    std::map<std::pair<std::int32_t, std::int32_t>, std::int32_t> id;
    for (std::size_t s = 0; s < m.surfaces.size(); ++s)
        id.emplace(std::make_pair(m.surfaces[s].inside, m.surfaces[s].outside), static_cast<std::int32_t>(s));
    const Topology t = buildTopology(m, TopologyParts::NodeMoves);
    const auto add = [&](Index q, bool interface) {
        const Quad& quad = t.quads[static_cast<std::size_t>(q)];
        SurfaceQuad s;
        s.nodes = quad.nodes;
        s.hex = quad.hex;
        const std::int32_t a = m.material[static_cast<std::size_t>(quad.hex[0])];
        const std::int32_t b = interface ? m.material[static_cast<std::size_t>(quad.hex[1])] : -1;
        const auto key = interface ? std::make_pair(std::min(a, b), std::max(a, b)) : std::make_pair(a, -1);
        const auto it = id.find(key);
        s.surface = it == id.end() ? -1 : it->second;
        s.material = key.first;
        p.quads.push_back(s);
    };
    for (Index q : t.boundaryQuads) add(q, false);
    for (Index q : t.interfaceQuads) add(q, true);
}

// A moved node on quads `qs`: surface nets over the crossings of its quads'
// segments, then onto the surface; its class.
void placeOnSurface(PlacedMesh& p, const Domain& d, std::size_t n, const std::vector<std::size_t>& qs, double maxStep) {
    HexMesh& m = p.a.mesh;
    const SurfaceQuad& first = p.quads[qs.front()];
    bool junction = first.surface < 0;
    Vec3 sum{0, 0, 0};
    int count = 0;
    for (std::size_t qi : qs) {
        const SurfaceQuad& q = p.quads[qi];
        junction = junction || q.surface != first.surface;
        const Vec3 c0 = centroid(p, q.hex[0]);
        Vec3 c1;
        if (q.hex[1] != kNone) {
            c1 = centroid(p, q.hex[1]);
        } else {
            Vec3 fc{0, 0, 0};
            for (Index v : q.nodes)
                for (int k = 0; k < 3; ++k) fc[k] += p.lattice[static_cast<std::size_t>(v)][k] / 4;
            for (int k = 0; k < 3; ++k) c1[k] = 2 * fc[k] - c0[k];
        }
        Vec3 x;
        if (!crossing(d, q.material, c0, c1, x)) continue;
        for (int k = 0; k < 3; ++k) sum[k] += x[k];
        ++count;
    }
    p.junction[n] = junction;
    Vec3 x = p.lattice[n];
    if (count) x = {sum[0] / count, sum[1] / count, sum[2] / count};
    if (!junction) newton(d, first.material, x, maxStep);
    // stay within `maxStep` of the lattice position: farther, the hexes
    // around could fold; the deviation check refines there instead
    const Vec3& l = p.lattice[n];
    const double dist = std::sqrt((x[0] - l[0]) * (x[0] - l[0]) + (x[1] - l[1]) * (x[1] - l[1]) + (x[2] - l[2]) * (x[2] - l[2]));
    if (dist > maxStep)
        for (int k = 0; k < 3; ++k) x[k] = l[k] + (x[k] - l[k]) * maxStep / dist;
    m.nodes[n] = x;
    m.nodeClass[n] = {NodeKind::Surface, std::max(first.surface, 0)};
}

// Per node: whether the hexes around it are those of the uniform mesh's node
// there: one kept hex per octant around a level-0 node, each with the label
// of the grid point in that octant, and no hex where that point is
// unlabelled. Then the uniform mesh's node (dual contouring of the same eight
// labels) is this node's.
std::vector<std::uint8_t> sameAsUniform(const PlacedMesh& p, const Labels& labels) {
    const HexMesh& m = p.a.mesh;
    const std::size_t n = m.nodeCount();
    std::vector<std::array<std::int32_t, 8>> octant(n);
    std::vector<std::uint8_t> ok(n, 1);
    for (std::size_t i = 0; i < n; ++i) {
        octant[i].fill(0);
        const auto q = keyCoords(p.a.nodeKeys[i]);
        if (q[0] % kS || q[1] % kS || q[2] % kS) ok[i] = 0;
    }
    for (std::size_t h = 0; h < m.hexCount(); ++h) {
        std::array<std::int64_t, 3> c{0, 0, 0};
        for (Index v : m.hexes[h]) {
            const auto q = keyCoords(p.a.nodeKeys[static_cast<std::size_t>(v)]);
            for (int k = 0; k < 3; ++k) c[k] += q[k];
        }
        for (Index v : m.hexes[h]) {
            const auto vi = static_cast<std::size_t>(v);
            if (!ok[vi]) continue;
            const auto q = keyCoords(p.a.nodeKeys[vi]);
            int o = 0;
            for (int k = 0; k < 3; ++k) {
                if (c[k] == 8 * q[k]) ok[vi] = 0;
                if (c[k] > 8 * q[k]) o |= 1 << k;
            }
            if (octant[vi][static_cast<std::size_t>(o)] != 0) ok[vi] = 0;  // two hexes in one octant
            octant[vi][static_cast<std::size_t>(o)] = m.material[h];
        }
    }
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
        if (!ok[i]) return;
        const auto q = keyCoords(p.a.nodeKeys[i]);
        for (int o = 0; o < 8 && ok[i]; ++o) {
            const int pi = static_cast<int>(q[0] / kS) - 1 + (o & 1), pj = static_cast<int>(q[1] / kS) - 1 + (o >> 1 & 1),
                      pk = static_cast<int>(q[2] / kS) - 1 + (o >> 2 & 1);
            ok[i] = octant[i][static_cast<std::size_t>(o)] == labels.at(pi, pj, pk);
        }
    });
    return ok;
}

// Per node: the shortest lattice edge of the hexes around it (how far it may
// move without leaving the region it stands for).
std::vector<double> shortestEdges(const PlacedMesh& p) {
    static constexpr int edge[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                        {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    std::vector<double> out(p.lattice.size(), std::numeric_limits<double>::infinity());
    for (const Hex& h : p.a.mesh.hexes)
        for (const auto& e : edge) {
            const auto a = static_cast<std::size_t>(h[static_cast<std::size_t>(e[0])]),
                       b = static_cast<std::size_t>(h[static_cast<std::size_t>(e[1])]);
            const Vec3 &x = p.lattice[a], &y = p.lattice[b];
            const double d = std::sqrt((x[0] - y[0]) * (x[0] - y[0]) + (x[1] - y[1]) * (x[1] - y[1]) + (x[2] - y[2]) * (x[2] - y[2]));
            out[a] = std::min(out[a], d);
            out[b] = std::min(out[b], d);
        }
    return out;
}

// Moves the moved nodes of inverted hexes (all nodes of inverted coarse
// hexes) back towards their lattice
// positions (where every hex is valid) until no hex they are in is inverted:
// halfway at a time, then all the way. The deviation check then judges the
// quads where they stand.
void holdBack(PlacedMesh& p) {
    HexMesh& m = p.a.mesh;
    std::vector<std::uint8_t> bad(m.hexCount(), 0);
    for (int round = 0; round < 6; ++round) {
        tbb::parallel_for(std::size_t{0}, m.hexCount(), [&](std::size_t h) {
            bool moved = p.a.hexLevel[h] > 0;
            for (Index v : m.hexes[h]) moved = moved || p.moved[static_cast<std::size_t>(v)];
            bad[h] = moved && !(minJacobianDeterminant(hexCoords(m, static_cast<Index>(h))) > 0);
        });
        // moved nodes, and the uniform nodes of coarse hexes (they are not
        // the uniform mesh's hexes there, so its node need not fit them)
        std::vector<Index> nodes;
        for (std::size_t h = 0; h < bad.size(); ++h)
            if (bad[h])
                for (Index v : m.hexes[h])
                    if (p.moved[static_cast<std::size_t>(v)] || p.a.hexLevel[h] > 0) nodes.push_back(v);
        if (nodes.empty()) return;
        std::sort(nodes.begin(), nodes.end());
        nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
        const double keep = round < 5 ? 0.5 : 0.0;
        for (Index v : nodes) {
            Vec3& x = m.nodes[static_cast<std::size_t>(v)];
            const Vec3& l = p.lattice[static_cast<std::size_t>(v)];
            for (int k = 0; k < 3; ++k) x[k] = l[k] + keep * (x[k] - l[k]);
        }
    }
}

}  // namespace

PlacedMesh placeAdaptive(const LeafHexes& leaves, const LeafLocator& locate, const Labels& labels,
                         const UniformNodes& uniformAt, const HexMesh& uniform, const Domain& domain) {
    PlacedMesh p;
    p.a = assembleAdaptive(leaves, labels.grid);
    HexMesh& m = p.a.mesh;
    m.surfaces = uniform.surfaces;
    m.curves = uniform.curves;
    const std::size_t n = m.nodeCount();
    p.lattice = m.nodes;
    p.moved.assign(n, 0);
    p.junction.assign(n, 0);
    std::vector<std::uint8_t> level(n, 0);
    std::vector<std::uint8_t> same = sameAsUniform(p, labels);
    const std::vector<double> reach = shortestEdges(p);
    const auto sp = labels.grid.spacing();
    const double h = std::max({sp[0], sp[1], sp[2]});
    // a template's hexes thinner than a grid step may share an octant
    for (std::size_t i = 0; i < n; ++i) same[i] = same[i] && reach[i] > 0.999 * std::min({sp[0], sp[1], sp[2]});
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
        level[i] = static_cast<std::uint8_t>(std::max(0, locate.levelAround(p.a.nodeKeys[i])));
        const Index v = same[i] ? uniformAt.at(p.a.nodeKeys[i]) : kNone;
        if (v == kNone) {
            p.moved[i] = 1;
            return;
        }
        m.nodes[i] = uniform.nodes[static_cast<std::size_t>(v)];
        m.nodeClass[i] = uniform.nodeClass[static_cast<std::size_t>(v)];
    });
    collectQuads(p);
    // the quads of each moved node (counting sort by node)
    std::vector<std::size_t> start(n + 1, 0);
    for (const SurfaceQuad& q : p.quads)
        for (Index v : q.nodes)
            if (p.moved[static_cast<std::size_t>(v)]) ++start[static_cast<std::size_t>(v) + 1];
    for (std::size_t i = 0; i < n; ++i) start[i + 1] += start[i];
    std::vector<std::size_t> items(start[n]);
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t qi = 0; qi < p.quads.size(); ++qi)
        for (Index v : p.quads[qi].nodes)
            if (p.moved[static_cast<std::size_t>(v)]) items[fill[static_cast<std::size_t>(v)]++] = qi;
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
        if (start[i] == start[i + 1]) return;
        const std::vector<std::size_t> qs(items.begin() + static_cast<std::ptrdiff_t>(start[i]),
                                          items.begin() + static_cast<std::ptrdiff_t>(start[i + 1]));
        double maxStep = h;
        for (int l = 0; l < level[i]; ++l) maxStep *= 3;
        placeOnSurface(p, domain, i, qs, std::min(maxStep, reach[i]));
    });
    holdBack(p);
    return p;
}

LeafLocator::LeafLocator(const RefinementTree& tree) : tree_(tree), side_(static_cast<std::size_t>(tree.top()) + 1) {
    std::int64_t s = 2 * kS;
    for (auto& v : side_) {
        v = s;
        s *= 3;
    }
}

Leaf LeafLocator::at(const HalfKey& h) const {
    for (int c = 0; c < 3; ++c)
        if (h[c] < 0) return {};
    for (int l = tree_.top(); l >= 1; --l) {
        const RefinementLevel& L = tree_.levels[static_cast<std::size_t>(l)];
        const std::int64_t s = side_[static_cast<std::size_t>(l)];
        const std::array<int, 3> c{static_cast<int>(h[0] / s), static_cast<int>(h[1] / s), static_cast<int>(h[2] / s)};
        if (!L.contains(c[0], c[1], c[2])) return {};
        if (!L.refined[L.index(c[0], c[1], c[2])]) return {l, c};
    }
    return {0, {static_cast<int>(h[0] / (2 * kS)), static_cast<int>(h[1] / (2 * kS)), static_cast<int>(h[2] / (2 * kS))}};
}

int LeafLocator::levelAround(NodeKey key) const {
    const auto q = keyCoords(key);
    int level = -1;
    for (int c = 0; c < 8; ++c) {
        const HalfKey h{2 * q[0] + ((c & 1) ? 1 : -1), 2 * q[1] + ((c & 2) ? 1 : -1), 2 * q[2] + ((c & 4) ? 1 : -1)};
        level = std::max(level, at(h).level);
    }
    return level;
}

}  // namespace isohex::octree

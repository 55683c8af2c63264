// Dual contouring: one hex per labelled grid point, corners at the dual
// vertices of the 8 cells around it.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <set>

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/SettingError.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/octree/DualContour.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "SegmentRoot.hpp"

namespace isohex::octree {

namespace {

Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// Cells are indexed by (ci, cj, ck) in [0, n]: cell c spans grid points
// c-1 .. c along each axis, so cells 0 and n stick out of the grid by half a
// step and their outside corners count as background.
struct CellGrid {
    std::array<int, 3> n;  // grid dims; cell dims are n + 1
    std::size_t index(int ci, int cj, int ck) const {
        return (static_cast<std::size_t>(ck) * (n[1] + 1) + cj) * (n[0] + 1) + ci;
    }
    std::size_t size() const {
        return static_cast<std::size_t>(n[0] + 1) * (n[1] + 1) * (n[2] + 1);
    }
};

// F = f_a - f_b (f_0 = 0): negative at a point of material a, positive at b.
double edgeFunction(const Domain& dom, std::int32_t a, std::int32_t b, const Vec3& x, Vec3* grad) {
    Vec3 ga{0, 0, 0}, gb{0, 0, 0};
    double f = 0;
    if (a != 0) f += dom.value(a, x, grad ? &ga : nullptr);
    if (b != 0) f -= dom.value(b, x, grad ? &gb : nullptr);
    if (grad) *grad = sub(ga, gb);
    return f;
}

// Hermite datum on the segment p (material a) - q (material b). Where the
// labels differ but the field does not change sign (non-manifold repair or
// --keep-largest changed a point) there is no crossing: the midpoint stands in.
void crossing(const Domain& dom, std::int32_t a, std::int32_t b, const Vec3& p, const Vec3& q, Vec3& point,
              Vec3& normal) {
    const Vec3 d = sub(q, p);
    const double f0 = edgeFunction(dom, a, b, p, nullptr), f1 = edgeFunction(dom, a, b, q, nullptr);
    double t = 0.5;
    if ((f0 < 0 && f1 > 0) || (f0 > 0 && f1 < 0))
        t = rootOnSegment([&](const Vec3& x) { return edgeFunction(dom, a, b, x, nullptr); }, p, q, f0, f1);
    // A grid point exactly on the surface (a label map's grid point half-way
    // between two voxels of different labels, as with --size 1.5 voxels, or an
    // integer iso value met by an integer scan) is where the surface crosses.
    // The midpoint would put the vertex up to half a cell off the surface, often
    // where the field is flat and nothing can project it back.
    else if (f1 == 0 && f0 != 0)
        t = 1.0;
    else if (f0 == 0 && f1 != 0)
        t = 0.0;
    point = {p[0] + t * d[0], p[1] + t * d[1], p[2] + t * d[2]};
    Vec3 g;
    edgeFunction(dom, a, b, point, &g);
    double len = std::sqrt(dot(g, g));
    if (!(len > 0) || !std::isfinite(len)) {
        g = d;
        len = std::sqrt(dot(d, d));
    }
    normal = {g[0] / len, g[1] / len, g[2] / len};
}

// A cell, in world coordinates: x = lower + axes * u with u in [0, 1]^3.
struct CellFrame {
    Eigen::Vector3d lower;
    const Eigen::Matrix3d& axes;
    const Eigen::Matrix3d& toCell;
    double margin;
    bool contains(const Eigen::Vector3d& x) const {
        const Eigen::Vector3d u = toCell * (x - lower);
        return (u.array() >= margin).all() && (u.array() <= 1.0 - margin).all();
    }
};

// Moves x onto the zero set of F = f_a - f_b without leaving the cell shrunk
// by the margin. First Newton steps along the gradient, each halved until it
// stays inside; if they stall short of the surface (the step would leave the
// cell, or the field is flat), the root closest to x on the segments from x to
// those corners of the shrunken cell where F has the other sign. If there is
// none, the surface crosses the cell only within the margin of a grid point
// (a grid value within a hair of the iso value: a speck of one point, or a
// dimple): x goes to the shrunken cell's corner next to the grid point of the
// other sign whose value is closest to the surface, as near to it as the
// margin allows. When no grid point of the cell has the other sign either (the
// repair or --keep-largest changed the labels: no surface crosses the cell),
// x stays where the QEF put it. `tol` is in world units.
// `field(point, gradient)` is the signed function whose zero set is the surface.
template <class Field>
Eigen::Vector3d ontoSurface(const Field& field, Eigen::Vector3d x, const CellFrame& cell,
                            const std::array<Vec3, 8>& corner, double tol) {
    auto F = [&](const Eigen::Vector3d& y, Vec3* g) { return field(Vec3{y(0), y(1), y(2)}, g); };
    auto newton = [&](Eigen::Vector3d& y) {
        for (int it = 0; it < 8; ++it) {
            Vec3 grad;
            const double f = F(y, &grad);
            const Eigen::Vector3d gr(grad[0], grad[1], grad[2]);
            const double g2 = gr.squaredNorm();
            if (!std::isfinite(f) || !(g2 > 0)) return false;
            if (std::abs(f) < tol * std::sqrt(g2)) return true;
            const Eigen::Vector3d step = -f / g2 * gr;
            double s = 1;
            while (!cell.contains(y + s * step) && s > 1.0 / 32) s *= 0.5;
            if (!cell.contains(y + s * step)) return false;
            y += s * step;
        }
        return false;
    };
    if (newton(x)) return x;
    const double f = F(x, nullptr);
    if (!std::isfinite(f) || f == 0) return x;
    auto other = [&](double v) { return (f < 0 && v > 0) || (f > 0 && v < 0); };
    auto shrunk = [&](int c) {
        const Eigen::Vector3d u(c & 1 ? 1 - cell.margin : cell.margin, c >> 1 & 1 ? 1 - cell.margin : cell.margin,
                                c >> 2 & 1 ? 1 - cell.margin : cell.margin);
        return Eigen::Vector3d(cell.lower + cell.axes * u);
    };
    const Vec3 xv{x(0), x(1), x(2)};
    double best = std::numeric_limits<double>::infinity();
    Eigen::Vector3d bestPoint = x;
    for (int c = 0; c < 8; ++c) {
        const Eigen::Vector3d q = shrunk(c);
        const double fq = F(q, nullptr);
        if (!other(fq)) continue;
        const Vec3 qv{q(0), q(1), q(2)};
        const double t = rootOnSegment([&](const Vec3& y) { return field(y, nullptr); }, xv, qv, f, fq);
        const double dist = t * (q - x).norm();
        if (dist < best) {
            best = dist;
            bestPoint = x + t * (q - x);
        }
    }
    if (best < std::numeric_limits<double>::infinity()) return bestPoint;
    int nearest = -1;
    double nearestValue = std::numeric_limits<double>::infinity();
    for (int c = 0; c < 8; ++c) {
        const double v = field(corner[c], nullptr);
        if (other(v) && std::abs(v) < nearestValue) {
            nearestValue = std::abs(v);
            nearest = c;
        }
    }
    if (nearest < 0) return x;
    Eigen::Vector3d y = shrunk(nearest);
    newton(y);
    return y;
}

// What classifyBoundaryNodes finds from the hexes' faces, straight from the
// grid and without building the mesh's topology: the quad dual to the grid
// edge p..p+e_d separates the hexes of p and p+e_d, and its 4 nodes are the
// cells around that edge. So a cell's node lies on the surfaces of the 12 grid
// edges of its cell. Surfaces are (material, -1) against the outside and
// (smaller, larger) between two materials, sorted, as surfacePatches has them.
template <class Hexed>
class GridClassifier {
public:
    using Tag = std::pair<std::int32_t, std::int32_t>;
    using Triple = std::array<std::int32_t, 3>;

    GridClassifier(const Labels& labels, const Hexed& hexed, const std::vector<Index>& node, const CellGrid& cg)
        : labels_(labels), hexed_(hexed), node_(node), cg_(cg) {}

    // The mesh's surface and curve lists, then every node's class.
    void classify(HexMesh& mesh) {
        collectSurfaces();
        mesh.surfaces.clear();
        for (const auto& [in, out] : tags_) mesh.surfaces.push_back(SurfaceTag{in, out, {}});
        mesh.curves = curves_;
        assignClasses(mesh);
    }

private:
    const Labels& labels_;
    const Hexed& hexed_;
    const std::vector<Index>& node_;
    const CellGrid& cg_;
    std::vector<Tag> tags_;       // every surface, sorted
    std::vector<Triple> curves_;  // every curve (its three materials), sorted

    // The surfaces of the (up to 12) grid edges of cell (ci, cj, ck); returns how many.
    int cellTags(int ci, int cj, int ck, std::array<Tag, 12>& out) const {
        std::array<bool, 8> h;
        std::array<std::int32_t, 8> m;
        bool uniform = true;
        for (int c = 0; c < 8; ++c) {
            const int i = ci - 1 + (c & 1), j = cj - 1 + (c >> 1 & 1), k = ck - 1 + (c >> 2 & 1);
            h[c] = hexed_(i, j, k);
            m[c] = labels_.at(i, j, k);
            uniform = uniform && h[c] == h[0] && m[c] == m[0];
        }
        if (uniform) return 0;
        int n = 0;
        for (int c = 0; c < 8; ++c)
            for (int d = 0; d < 3; ++d) {
                const int e = c | (1 << d);
                if (e == c) continue;
                if (h[c] && h[e]) {
                    if (m[c] != m[e]) out[n++] = {std::min(m[c], m[e]), std::max(m[c], m[e])};
                } else if (h[c] || h[e]) {
                    out[n++] = {h[c] ? m[c] : m[e], -1};
                }
            }
        return n;
    }
    // The materials meeting along a curve node's cell, when exactly three meet
    // there (-1: outside) and at most one of them is not a material (the box
    // around a meshed exterior keeps its curve nodes fixed); else none.
    static bool curveOf(const std::array<Tag, 12>& t, int n, Triple& out) {
        std::array<std::int32_t, 24> m{};
        int k = 0;
        for (int e = 0; e < n; ++e) {
            m[k++] = t[e].first;
            m[k++] = t[e].second;
        }
        std::sort(m.begin(), m.begin() + k);
        k = static_cast<int>(std::unique(m.begin(), m.begin() + k) - m.begin());
        if (k != 3 || m[1] <= 0) return false;
        out = {m[0], m[1], m[2]};
        return true;
    }
    static bool onCurve(const std::array<Tag, 12>& t, int n) {
        for (int e = 1; e < n; ++e)
            if (t[e] != t[0]) return true;
        return false;
    }

    // The surfaces and curves of all node cells (per thread, then merged and sorted).
    void collectSurfaces() {
        const auto [nx, ny, nz] = labels_.grid.dims;
        tbb::enumerable_thread_specific<std::pair<std::set<Tag>, std::set<Triple>>> local;
        tbb::parallel_for(0, nz + 1, [&](int ck) {
            auto& [set, curves] = local.local();
            std::array<Tag, 12> t;
            Triple c;
            for (int cj = 0; cj <= ny; ++cj)
                for (int ci = 0; ci <= nx; ++ci) {
                    if (node_[cg_.index(ci, cj, ck)] == kNone) continue;
                    const int n = cellTags(ci, cj, ck, t);
                    for (int e = 0; e < n; ++e) set.insert(t[e]);
                    if (onCurve(t, n) && curveOf(t, n, c)) curves.insert(c);
                }
        });
        std::set<Tag> all;
        std::set<Triple> allCurves;
        for (const auto& s : local) {
            all.insert(s.first.begin(), s.first.end());
            allCurves.insert(s.second.begin(), s.second.end());
        }
        tags_.assign(all.begin(), all.end());
        curves_.assign(allCurves.begin(), allCurves.end());
    }

    // Each node: interior, on one surface, or on a curve (named when three
    // materials meet there).
    void assignClasses(HexMesh& mesh) const {
        const auto [nx, ny, nz] = labels_.grid.dims;
        tbb::parallel_for(0, nz + 1, [&](int ck) {
            std::array<Tag, 12> t;
            Triple c;
            for (int cj = 0; cj <= ny; ++cj)
                for (int ci = 0; ci <= nx; ++ci) {
                    const Index id = node_[cg_.index(ci, cj, ck)];
                    if (id == kNone) continue;
                    const int n = cellTags(ci, cj, ck, t);
                    NodeClass cls{};
                    for (int e = 0; e < n; ++e) {
                        const auto s = static_cast<std::int32_t>(std::lower_bound(tags_.begin(), tags_.end(), t[e]) - tags_.begin());
                        if (cls.kind == NodeKind::Interior) cls = {NodeKind::Surface, s};
                        else if (cls.kind == NodeKind::Surface && cls.id != s) cls = {NodeKind::Curve, -1};
                    }
                    if (cls.kind == NodeKind::Curve && curveOf(t, n, c))
                        cls.id = static_cast<std::int32_t>(std::lower_bound(curves_.begin(), curves_.end(), c) - curves_.begin());
                    mesh.nodeClass[id] = cls;
                }
        });
    }
};

template <class Hexed>
void classifyFromGrid(HexMesh& mesh, const Labels& labels, const Hexed& hexed, const std::vector<Index>& node,
                      const CellGrid& cg) {
    GridClassifier<Hexed>(labels, hexed, node, cg).classify(mesh);
}

// A vertex of a crossed cell as placed: its node, QEF point and cell centre.
struct CrossedVertex {
    Index id;
    Vec3 qef, centre;
};

// The vertices of crossed cells and how far each is pulled back from where
// dual contouring put it (its target: the surface point, or the QEF point of
// a cell it does not project) towards the centre of its cell, along the path
// target -> QEF point -> centre. Level l < 4 puts node qef[i] at
// qef + 2^-l (target - qef), level 4 at the QEF point, levels 5 and 6 half
// and three quarters of the way from the QEF point to the centre, level 7
// (kTop) at the centre; 255 marks a node of an uncrossed cell (at its centre
// already). A hex whose crossed corners are all at their centres is the grid's
// own cube (positive), so raising levels always ends with every hex valid.
struct SurfaceMoves {
    static constexpr int kTopMax = 7;
    int kTop = kTopMax;  // 4 (the QEF point) without ExtractOptions::validStart
    bool centre = true;  // the centre Jacobian counts too (not without ExtractOptions::validStart)
    std::vector<CrossedVertex> qef;  // ascending node
    std::vector<Vec3> onSurface;     // the same nodes' targets (surface point, or the QEF point)
    std::vector<std::uint8_t> level;          // per mesh node

    // Position of node qef[i] at level l.
    Vec3 at(std::size_t i, int l) const {
        if (l >= kTopMax) return qef[i].centre;
        const Vec3& a = qef[i].qef;
        if (l > 4) {
            const double sc = l == 5 ? 0.5 : 0.75;
            const Vec3& c = qef[i].centre;
            return Vec3{a[0] + sc * (c[0] - a[0]), a[1] + sc * (c[1] - a[1]), a[2] + sc * (c[2] - a[2])};
        }
        const Vec3& b = onSurface[i];
        if (l == 0 && centre) return b;  // (without validStart: qef + 1 (b - qef), as before, to the bit)
        const double sc = l == 4 ? 0.0 : std::ldexp(1.0, -l);
        return Vec3{a[0] + sc * (b[0] - a[0]), a[1] + sc * (b[1] - a[1]), a[2] + sc * (b[2] - a[2])};
    }
    // Index in qef of node id.
    std::size_t slot(Index id) const {
        return static_cast<std::size_t>(
            std::lower_bound(qef.begin(), qef.end(), id, [](const auto& e, Index v) { return e.id < v; }) - qef.begin());
    }
    bool valid(const HexCoords& x) const { return minCornerDeterminant(x) > 0 && (!centre || centreDeterminant(x) > 0); }
    // The fewest extra levels for the crossed corners of an inverted hex
    // (corner positions x0) that make it valid; -1 if it has no corner below kTop.
    int extraLevels(const Hex& hex, const HexCoords& x0) const {
        for (int extra = 1; extra <= kTop; ++extra) {
            HexCoords x = x0;
            bool raised = false;
            for (int c = 0; c < 8; ++c) {
                const std::uint8_t l = level[static_cast<std::size_t>(hex[c])];
                if (l < kTop) {
                    x[c] = at(slot(hex[c]), std::min(kTop, l + extra));
                    raised = true;
                }
            }
            if (!raised) return -1;
            if (valid(x)) return extra;
        }
        return -1;
    }
    // One round, decided from the positions at its start: every inverted hex
    // with a crossed corner asks its crossed corners for the levels it needs;
    // a node takes the largest level asked (`wanted`, a copy of `level` on
    // entry). Returns whether any hex asked.
    bool askLevels(const HexMesh& mesh, std::vector<std::uint8_t>& wanted) const {
        std::atomic<bool> changed{false};
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, mesh.hexes.size(), 4096), [&](const auto& r) {
            for (std::size_t h = r.begin(); h != r.end(); ++h) {
                const Hex& hex = mesh.hexes[h];
                bool movable = false;
                for (Index v : hex) movable = movable || level[static_cast<std::size_t>(v)] < kTop;
                if (!movable) continue;
                const HexCoords x0 = hexCoords(mesh, static_cast<Index>(h));
                if (valid(x0)) continue;
                const int found = extraLevels(hex, x0);
                if (found < 0) continue;
                for (Index v : hex) {
                    const std::uint8_t l = level[static_cast<std::size_t>(v)];
                    if (l >= kTop) continue;
                    const auto want = static_cast<std::uint8_t>(std::min(kTop, l + found));
                    std::atomic_ref<std::uint8_t> w(wanted[static_cast<std::size_t>(v)]);
                    std::uint8_t cur = w.load(std::memory_order_relaxed);
                    while (cur < want && !w.compare_exchange_weak(cur, want, std::memory_order_relaxed)) {
                    }
                    changed = true;
                }
            }
        });
        return changed;
    }
};

// One extraction's state, which the phases of dualContourHexes fill in order.
struct DualContouring {
    const Labels& labels;
    const Domain& domain;
    const ExtractOptions& opt;
    const Grid& g;
    const CellGrid cg;
    const int nx, ny, nz;
    Eigen::Matrix3d axes;     // columns: the grid axes
    Eigen::Matrix3d toCell;   // world offset -> cell coordinates
    double surfaceTolerance;  // vertices count as on the surface within this distance (world units)

    std::vector<Index> node;             // per cell: its node, kNone when no hex uses the cell
    std::vector<std::size_t> perSlab;    // nodes in the cell slabs before slab ck + 1 (after markNodeCells)
    std::size_t nodeCount = 0;
    HexMesh mesh;
    // vertices of crossed cells with their QEF point and cell centre, per cell slab in node order
    std::vector<std::vector<CrossedVertex>> qefSlab;
    std::size_t crossed = 0, clamped = 0;
    std::vector<Index> heldBack;
    std::vector<Vec3> heldBackAt;

    DualContouring(const Labels& l, const Domain& d, const ExtractOptions& o)
        : labels(l), domain(d), opt(o), g(l.grid), cg{l.grid.dims}, nx(g.dims[0]), ny(g.dims[1]), nz(g.dims[2]) {
        for (int a = 0; a < 3; ++a)
            for (int c = 0; c < 3; ++c) axes(c, a) = g.axes[a][c];
        toCell = axes.inverse();
        const auto spacing = g.spacing();
        surfaceTolerance = 1e-3 * std::min({spacing[0], spacing[1], spacing[2]});
    }

    // Whether grid point (i, j, k) gets a hex.
    bool hexed(int i, int j, int k) const {
        const std::int32_t m = labels.at(i, j, k);
        return opt.meshExterior ? (i >= 0 && j >= 0 && k >= 0 && i < nx && j < ny && k < nz) : m != 0;
    }
    // out[ci]: point ci-1 or ci of grid row (j, k) is hexed.
    void hexedPair(int j, int k, std::vector<std::uint8_t>& out) const {
        std::fill(out.begin(), out.end(), 0);
        if (j < 0 || k < 0 || j >= ny || k >= nz) return;
        const std::int32_t* row = &labels.material[g.index(0, j, k)];
        for (int i = 0; i < nx; ++i)
            if (opt.meshExterior || row[i] != 0) out[i] = out[i + 1] = 1;
    }

    // 1. Which cells carry a node: those around a hexed point. Counted per
    // slab so that placeNodes can number them in cell order in parallel.
    void markNodeCells() {
        node.assign(cg.size(), kNone);
        perSlab.assign(static_cast<std::size_t>(nz) + 2, 0);
        tbb::parallel_for(0, nz + 1, [&](int ck) {
            std::size_t count = 0;
            std::array<std::vector<std::uint8_t>, 4> rows;
            for (auto& r : rows) r.resize(static_cast<std::size_t>(nx) + 1);
            for (int cj = 0; cj <= ny; ++cj) {
                for (int r = 0; r < 4; ++r) hexedPair(cj - 1 + (r & 1), ck - 1 + (r >> 1), rows[r]);
                for (int ci = 0; ci <= nx; ++ci)
                    if (rows[0][ci] | rows[1][ci] | rows[2][ci] | rows[3][ci]) {
                        node[cg.index(ci, cj, ck)] = 0;
                        ++count;
                    }
            }
            perSlab[static_cast<std::size_t>(ck) + 1] = count;
        });
        for (std::size_t s = 1; s < perSlab.size(); ++s) perSlab[s] += perSlab[s - 1];
        nodeCount = perSlab[static_cast<std::size_t>(nz) + 1];
        if (nodeCount > static_cast<std::size_t>(std::numeric_limits<Index>::max()))
            throw SettingError({"the mesh would have more than 2^31 nodes; use a larger ", Setting::Size});
    }

    // The mesh's node arrays, with room for the boundary sheet the pipeline
    // pillows in next (its nodes and hexes are a small share of a solid's),
    // so pillowing appends in place instead of copying the arrays; capacity
    // that is never written costs address space only.
    void allocateNodes() {
        mesh.nodes.reserve(nodeCount + nodeCount / 4);
        mesh.nodeClass.reserve(nodeCount + nodeCount / 4);
        mesh.nodes.resize(nodeCount);
        mesh.nodeClass.resize(nodeCount);
    }

    // The QEF minimiser of the Hermite data on the cell edges whose ends
    // (materials m, points p) differ, relative to their mass point with a
    // truncated pseudo-inverse, so flat or degenerate configurations stay
    // near the mass point.
    Eigen::Vector3d qefMinimiser(const Domain& cellDomain, const std::array<std::int32_t, 8>& m,
                                 const std::array<Vec3, 8>& p) const {
        Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
        Eigen::Vector3d atb = Eigen::Vector3d::Zero(), mass = Eigen::Vector3d::Zero();
        std::array<std::pair<Vec3, Vec3>, 12> data;
        int n = 0;
        for (int c = 0; c < 8; ++c)
            for (int d = 0; d < 3; ++d) {
                const int e = c | (1 << d);
                if (e == c || m[c] == m[e]) continue;
                crossing(cellDomain, m[c], m[e], p[c], p[e], data[n].first, data[n].second);
                mass += Eigen::Vector3d(data[n].first[0], data[n].first[1], data[n].first[2]);
                ++n;
            }
        mass /= n;
        for (int s = 0; s < n; ++s) {
            const Eigen::Vector3d nrm(data[s].second[0], data[s].second[1], data[s].second[2]);
            const Eigen::Vector3d pt(data[s].first[0], data[s].first[1], data[s].first[2]);
            ata += nrm * nrm.transpose();
            atb += nrm * nrm.dot(pt - mass);
        }
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(ata);
        const Eigen::Vector3d lambda = eig.eigenvalues();
        const double cut = opt.qefTruncation * opt.qefTruncation * lambda.maxCoeff();
        Eigen::Vector3d x = mass;
        for (int s = 0; s < 3; ++s)
            if (lambda(s) > cut && lambda(s) > 0) {
                const Eigen::Vector3d v = eig.eigenvectors().col(s);
                x += v * (v.dot(atb) / lambda(s));
            }
        return x;
    }

    // Keeps x inside its cell (lowest corner `lower`) shrunk by the margin;
    // returns whether it had to move.
    bool keepInCell(Eigen::Vector3d& x, const Eigen::Vector3d& lower) const {
        Eigen::Vector3d u = toCell * (x - lower);
        bool clampedHere = false;
        for (int a = 0; a < 3; ++a) {
            const double lo = opt.cellMargin, hi = 1.0 - opt.cellMargin;
            if (u(a) < lo || u(a) > hi) {
                u(a) = std::clamp(u(a), lo, hi);
                clampedHere = true;
            }
        }
        if (clampedHere) x = lower + axes * u;
        return clampedHere;
    }

    // x moved onto the surface between the two materials of the cell, or,
    // where the outside meets two or more materials, onto the boundary of
    // their union (the outer surface there); x itself otherwise.
    Eigen::Vector3d ontoCellSurface(const Domain& cellDomain, const std::array<std::int32_t, 8>& m,
                                    const std::array<Vec3, 8>& p, const Eigen::Vector3d& x,
                                    const Eigen::Vector3d& lower) const {
        std::int32_t ma = m[0], mb = m[0];
        bool two = true;
        for (int c = 1; c < 8; ++c)
            if (m[c] != ma) {
                if (mb == ma) mb = m[c];
                else if (m[c] != mb) two = false;
            }
        bool outerJunction = false;
        if (!two && !opt.meshExterior) {
            bool outside = false;
            for (int c = 0; c < 8; ++c) outside = outside || m[c] == 0;
            outerJunction = outside && std::isfinite(cellDomain.unionValue(Vec3{x(0), x(1), x(2)}));
        }
        if (!opt.projectVertices || !(two || outerJunction)) return x;
        if (ma > mb) std::swap(ma, mb);  // sign of F does not matter for the root
        const CellFrame frame{lower, axes, toCell, opt.cellMargin};
        if (two)
            return ontoSurface([&](const Vec3& y, Vec3* gr) { return edgeFunction(cellDomain, ma, mb, y, gr); }, x, frame,
                               p, surfaceTolerance);
        return ontoSurface([&](const Vec3& y, Vec3* gr) { return cellDomain.unionValue(y, gr); }, x, frame, p,
                           surfaceTolerance);
    }

    // What placeNode adds up per slab.
    struct SlabTally {
        std::size_t crossed = 0, clamped = 0;
        std::vector<CrossedVertex>& crossedVertices;  // vertices of crossed cells, with QEF point and centre
    };

    // Node `id` of cell (ci, cj, ck): its centre when no surface crosses the
    // cell (or with cellCentres), else the QEF minimiser kept inside the
    // cell and moved onto the surface.
    void placeNode(int ci, int cj, int ck, Index id, SlabTally& tally) {
        std::array<std::int32_t, 8> m;
        std::array<Vec3, 8> p;
        bool mixed = false;
        for (int c = 0; c < 8; ++c) {
            const int i = ci - 1 + (c & 1), j = cj - 1 + (c >> 1 & 1), k = ck - 1 + (c >> 2 & 1);
            m[c] = labels.at(i, j, k);
            p[c] = g.point(i, j, k);
            mixed = mixed || m[c] != m[0];
        }
        const Vec3 centre = g.point(ci - 0.5, cj - 0.5, ck - 0.5);
        tally.crossed += mixed;
        if (!mixed || opt.cellCentres) {
            mesh.nodes[id] = centre;
            return;
        }
        const Domain& cellDomain = domain.within(centre);  // every query below stays in this cell
        Eigen::Vector3d x = qefMinimiser(cellDomain, m, p);
        const Eigen::Vector3d lower(g.point(ci - 1, cj - 1, ck - 1)[0], g.point(ci - 1, cj - 1, ck - 1)[1],
                                    g.point(ci - 1, cj - 1, ck - 1)[2]);
        if (keepInCell(x, lower)) ++tally.clamped;
        const Eigen::Vector3d qef = x;
        x = ontoCellSurface(cellDomain, m, p, x, lower);
        // Vertices of cells where three or more materials meet that stay at
        // their QEF point (on no one surface) stay there: held back, those
        // curve nodes came back to their curve worse.
        std::int32_t ma = m[0], mb = m[0];
        bool several = false;
        for (int c = 1; c < 8; ++c)
            if (m[c] != ma && m[c] != mb) {
                if (mb == ma) mb = m[c];
                else several = true;
            }
        if (opt.validStart ? !(several && x == qef) : x != qef) tally.crossedVertices.push_back({id, Vec3{qef(0), qef(1), qef(2)}, centre});
        mesh.nodes[id] = {x(0), x(1), x(2)};
    }

    // 2. Node positions, numbered in cell order, slab by slab in parallel.
    // Vertices of crossed cells keep their QEF point and cell centre in
    // qefSlab in case their position inverts a hex (holdBackInvertingMoves).
    void placeNodes() {
        qefSlab.assign(static_cast<std::size_t>(nz) + 1, {});
        std::atomic<std::size_t> crossedCells{0}, clampedVertices{0};
        tbb::parallel_for(0, nz + 1, [&](int ck) {
            Index next = static_cast<Index>(perSlab[static_cast<std::size_t>(ck)]);
            SlabTally tally{0, 0, qefSlab[static_cast<std::size_t>(ck)]};
            for (int cj = 0; cj <= ny; ++cj)
                for (int ci = 0; ci <= nx; ++ci) {
                    Index& id = node[cg.index(ci, cj, ck)];
                    if (id == kNone) continue;
                    id = next++;
                    placeNode(ci, cj, ck, id, tally);
                }
            crossedCells += tally.crossed;
            clampedVertices += tally.clamped;
        });
        crossed = crossedCells;
        clamped = clampedVertices;
    }

    // 3. Hexes: one per hexed grid point, in point order. VTK corner c sits
    // at offset ref[c]; a mirrored grid swaps two corner pairs so every hex
    // keeps a positive Jacobian.
    void buildHexes() {
        std::vector<std::size_t> hexSlab(static_cast<std::size_t>(nz) + 1, 0);
        tbb::parallel_for(0, nz, [&](int k) {
            std::size_t c = 0;
            for (int j = 0; j < ny; ++j)
                for (int i = 0; i < nx; ++i) c += hexed(i, j, k);
            hexSlab[static_cast<std::size_t>(k) + 1] = c;
        });
        for (std::size_t s = 1; s < hexSlab.size(); ++s) hexSlab[s] += hexSlab[s - 1];
        mesh.hexes.reserve(hexSlab.back() + hexSlab.back() / 4);
        mesh.material.reserve(hexSlab.back() + hexSlab.back() / 4);
        mesh.hexes.resize(hexSlab.back());
        mesh.material.resize(hexSlab.back());
        static constexpr int ref[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                          {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
        const bool mirrored = g.determinant() < 0;
        tbb::parallel_for(0, nz, [&](int k) {
            std::size_t h = hexSlab[static_cast<std::size_t>(k)];
            for (int j = 0; j < ny; ++j)
                for (int i = 0; i < nx; ++i) {
                    if (!hexed(i, j, k)) continue;
                    Hex hex;
                    for (int c = 0; c < 8; ++c) hex[c] = node[cg.index(i + ref[c][0], j + ref[c][1], k + ref[c][2])];
                    if (mirrored) {
                        std::swap(hex[1], hex[3]);
                        std::swap(hex[5], hex[7]);
                    }
                    mesh.hexes[h] = hex;
                    mesh.material[h] = labels.material[g.index(i, j, k)];
                    ++h;
                }
        });
    }

    // 4. Placing vertices on the surface (or at QEF points) must not leave a
    // hex inverted. Where a hex with corners in crossed cells is inverted,
    // those corners are pulled back along target -> QEF point -> cell centre
    // (SurfaceMoves::at) by the fewest levels that make it valid. A node
    // takes the most levels any of its hexes asks for; pulling back can
    // invert a neighbour, so repeat (levels only rise). This ends with every
    // hex valid: a hex whose crossed corners are at their cell centres is the
    // grid's cube around its point, so an inverted hex can always ask, and
    // levels are bounded. Each round decides from the positions at its start,
    // so the result does not depend on the thread count. The mesh keeps every
    // vertex at its target; the held-back (valid) positions go to the caller,
    // who starts the sheet and the optimiser from them.
    void holdBackInvertingMoves() {
        SurfaceMoves mv;
        if (!opt.validStart) {
            mv.kTop = 4;
            mv.centre = false;
        }
        for (auto& v : qefSlab) mv.qef.insert(mv.qef.end(), v.begin(), v.end());
        qefSlab.clear();
        mv.onSurface.resize(mv.qef.size());
        for (std::size_t i = 0; i < mv.qef.size(); ++i) mv.onSurface[i] = mesh.nodes[static_cast<std::size_t>(mv.qef[i].id)];
        mv.level.assign(nodeCount, 255);
        for (const CrossedVertex& v : mv.qef) mv.level[static_cast<std::size_t>(v.id)] = 0;
        std::vector<std::uint8_t> wanted;
        while (!mv.qef.empty()) {  // at most kTop rounds per crossed vertex; a few in practice
            wanted = mv.level;
            if (!mv.askLevels(mesh, wanted)) break;
            mv.level.swap(wanted);
            for (std::size_t i = 0; i < mv.qef.size(); ++i) {
                const auto id = static_cast<std::size_t>(mv.qef[i].id);
                mesh.nodes[id] = mv.at(i, mv.level[id]);
            }
        }
        for (std::size_t i = 0; i < mv.qef.size(); ++i) {
            const Index id = mv.qef[i].id;
            if (mv.level[static_cast<std::size_t>(id)] == 0) continue;
            heldBack.push_back(id);
            heldBackAt.push_back(mesh.nodes[static_cast<std::size_t>(id)]);
            mesh.nodes[static_cast<std::size_t>(id)] = mv.onSurface[i];
        }
    }

    // 5. The statistics, and the nodes' classes straight from the grid.
    HexMesh finish(ExtractStats* stats) {
        if (stats) {
            stats->crossedCells = crossed;
            stats->clampedVertices = clamped;
            stats->heldBack = std::move(heldBack);
            stats->heldBackAt = std::move(heldBackAt);
        }
        classifyFromGrid(mesh, labels, [&](int i, int j, int k) { return hexed(i, j, k); }, node, cg);
        return std::move(mesh);
    }
};

}  // namespace

HexMesh dualContourHexes(const Labels& labels, const Domain& domain, const ExtractOptions& opt, ExtractStats* stats) {
    const auto [nx, ny, nz] = labels.grid.dims;
    if (nx < 2 || ny < 2 || nz < 2) throw Error("the sampling grid is too small to mesh (fewer than 2 points per axis)");
    DualContouring dc(labels, domain, opt);
    dc.markNodeCells();
    dc.allocateNodes();
    dc.placeNodes();
    dc.buildHexes();
    dc.holdBackInvertingMoves();
    return dc.finish(stats);
}

}  // namespace isohex::octree

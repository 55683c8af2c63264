#include "isohex/smoothing/Optimize.hpp"
#include "isohex/core/VecMath.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/Colouring.hpp"
#include "isohex/smoothing/NodeObjective.hpp"

namespace isohex::smoothing {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Curve: a node on a curve (where three materials or two surfaces meet). With
// a projector that knows curves it slides along its curve in the mean-ratio
// phase; in any case it may move in the last-resort untangling, like a
// released surface node.
enum class Mode : std::uint8_t { Frozen, Interior, Surface, Curve };

// Fixed-size blocks summed in parallel, block sums added in block order: the
// same floating-point result for any thread count.
constexpr std::size_t kBlock = 4096;

struct ObjectiveSum {
    double sum = 0;           // sum of per-hex inverse mean ratios over finite hexes
    std::size_t finite = 0;   // hexes with all corner determinants > 0
};

// The sum over hexes 0..H-1 of q(h) where it is finite, in fixed blocks.
template <class Q>
ObjectiveSum blockSum(std::size_t H, Q q) {
    const std::size_t blocks = (H + kBlock - 1) / kBlock;
    std::vector<ObjectiveSum> part(blocks);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks), [&](const auto& r) {
        for (std::size_t b = r.begin(); b != r.end(); ++b) {
            ObjectiveSum s;
            for (std::size_t h = b * kBlock, e = std::min(H, h + kBlock); h < e; ++h) {
                const double v = q(h);
                if (std::isfinite(v)) {
                    s.sum += v;
                    ++s.finite;
                }
            }
            part[b] = s;
        }
    });
    ObjectiveSum total;
    for (const ObjectiveSum& s : part) {
        total.sum += s.sum;
        total.finite += s.finite;
    }
    return total;
}

ObjectiveSum objectiveSum(const HexMesh& mesh) {
    return blockSum(mesh.hexCount(), [&](std::size_t h) { return inverseMeanRatio(hexCoords(mesh, static_cast<Index>(h))); });
}

double meanOf(const ObjectiveSum& s) { return s.finite ? s.sum / static_cast<double>(s.finite) : 0.0; }

// Hexes with a corner or centre determinant <= 0 (or not a number).
std::size_t invertedCount(const HexMesh& mesh) {
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, mesh.hexCount(), kBlock), std::size_t{0},
        [&](const auto& r, std::size_t n) {
            for (std::size_t h = r.begin(); h != r.end(); ++h)
                n += !(minJacobianDeterminant(hexCoords(mesh, static_cast<Index>(h))) > 0);
            return n;
        },
        std::plus<>());
}

// With `terms` describing the node moved by `applied` from its original
// position: true if moving it by `trial` (from the original) instead leaves
// every corner that was positive at the original position positive.
bool keepsValidCornersValid(const CornerTerm* terms, std::size_t n, const Vector3& applied, const Vector3& trial) {
    for (std::size_t i = 0; i < n; ++i) {
        Matrix3 original = terms[i].A, moved = terms[i].A;
        displaceFrame(original, terms[i].role, -applied);
        displaceFrame(moved, terms[i].role, trial - applied);
        if (cornerDeterminant(original) > 0 && !(cornerDeterminant(moved) > 0)) return false;
    }
    return true;
}

inline void raise(std::uint8_t& flag) { std::atomic_ref<std::uint8_t>(flag).store(1, std::memory_order_relaxed); }

class Smoother {
public:
    Smoother(HexMesh& mesh, const SurfaceProjector* projector, const SmoothingOptions& opt, const Progress& progress,
             const Topology* topology)
        : mesh_(mesh), projector_(projector), opt_(opt), progress_(progress),
          topo_(topology ? *topology : ownTopology_) {}

    SmoothingResult run(bool meanRatio);

private:
    void setUp();
    void thinCurveBands(const std::vector<std::int32_t>& quadSurface);
    void untanglePhase();
    // One untangling phase, with the valid-corner guard or without it; a phase
    // without it that ends with more than `before` inverted hexes is undone
    // (returns false then).
    bool untangleRound(bool guard, std::size_t before);
    void returnToSurface();
    // With `onlyTouched`, only nodes that untangling moved since the last
    // mean-ratio phase (and their neighbours) start active: the rest is
    // where the previous phase left it.
    void meanRatioPhase(const ObjectiveSum& start, bool onlyTouched = false);
    // One visit of a node: how it moved and where it ends up.
    struct Visit {
        NodeMove move;
        double length = 0;  // local edge length
        Vec3 position{};    // the new position when move.steps > 0
    };
    Visit interiorStep(Index v, std::vector<CornerTerm>& buf) const;
    Visit surfaceStep(Index v, std::vector<CornerTerm>& buf) const;
    Visit untangleStep(Index v, std::vector<CornerTerm>& buf) const;
    Visit untangleSurfaceStep(Index v, std::vector<CornerTerm>& buf) const;
    // A curve node: towards the mean of its curve neighbours, then onto the curve.
    Visit curveStep(Index v, std::vector<CornerTerm>& buf) const;
    Visit curveSlide(Index v, std::vector<CornerTerm>& buf) const;  // curveStep without the final snap
    // Area-weighted centroid and unit normal of the node's surface quads; false if it has none.
    bool surfaceFrame(std::size_t v, Vector3& centroid, Vector3& normal) const;
    static Vec3 displaced(const Vec3& x, const Vector3& d) { return {x[0] + d[0], x[1] + d[1], x[2] + d[2]}; }
    void report(std::string_view stage, double fraction) const {
        if (progress_) progress_(stage, std::clamp(fraction, 0.0, 1.0));
    }
    // Each colour is one parallel loop; nodes of a colour share no hex, so the
    // order in which threads take them cannot change the result.
    template <class Fn>
    void sweepColours(const std::vector<std::vector<Index>>& lists, Fn visit) {
        for (const auto& list : lists)
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, list.size(), 16), [&](const auto& r) {
                for (std::size_t i = r.begin(); i != r.end(); ++i) visit(list[i]);
            });
    }
    // Every change of a node's position goes through here (or marks
    // nodeMoved_ itself), so that refreshHexStates sees it.
    void moveNode(std::size_t v, const Vec3& p) {
        mesh_.nodes[v] = p;
        nodeMoved_[v] = 1;
    }
    // Brings hexImr_ and hexInverted_ up to date: on the first call every
    // hex, after that only the hexes of nodes moved since the last call.
    void refreshHexStates();
    // Whole-mesh figures between phases (about 40 of them on ch2bet at 1 mm,
    // 0.08 s each when every hex was evaluated again), the same values a full
    // pass gives: objectiveSum(mesh_), invertedCount(mesh_).
    ObjectiveSum objectiveNow() {
        refreshHexStates();
        return blockSum(hexImr_.size(), [&](std::size_t h) { return hexImr_[h]; });
    }
    std::size_t invertedNow() {
        refreshHexStates();
        return static_cast<std::size_t>(std::count(hexInverted_.begin(), hexInverted_.end(), std::uint8_t{1}));
    }
    void markNeighbours(Index v, std::vector<std::uint8_t>& a, std::vector<std::uint8_t>& b) {
        for (const Index* h = topo_.nodeHexes.begin(v); h != topo_.nodeHexes.end(v); ++h)
            for (Index u : mesh_.hexes[static_cast<std::size_t>(*h)]) {
                raise(a[static_cast<std::size_t>(u)]);
                raise(b[static_cast<std::size_t>(u)]);
            }
    }

    HexMesh& mesh_;
    const SurfaceProjector* projector_;
    const SmoothingOptions& opt_;
    const Progress& progress_;

    Topology ownTopology_;  // built in setUp when the caller gave none
    const Topology& topo_;  // the caller's topology of mesh_, or ownTopology_
    std::vector<Mode> mode_;
    NodeColouring colouring_;
    Csr nodeSurfaceQuads_;  // per node, the surface quads of its own surface (Surface nodes only)
    Csr nodeCurveNeighbours_;  // per Curve node, the nodes joined to it by an edge of the same curve
    std::size_t maxTerms_ = 0;
    std::unique_ptr<tbb::enumerable_thread_specific<std::vector<CornerTerm>>> buffers_;
    std::vector<std::uint8_t> everMoved_;
    // Where each node started and the mean length of its edges there: no
    // untangling move takes a node farther than untangleMaxTravel of those
    // lengths from its start. Knupp's target (beta ~ L^3) grows with the
    // edges a node stretches, so without a bound a node could chase it across
    // the mesh (ch2bet 2 mm: surface nodes 80 mm from where they started).
    std::vector<double> refLength_;
    std::vector<Vec3> start_;
    std::vector<std::uint8_t> touched_;  // moved by untangling since the last mean-ratio phase
    bool guarded_ = true;  // untangling moves may not invert a valid corner
    bool releaseSurface_ = false;  // surface nodes untangle in 3-D, off their surface
    std::vector<std::uint8_t> released_;
    std::vector<Vec3> anchor_;  // surface positions when the release began
    std::vector<double> anchorLength_;  // local edge length there and then
    double releaseLimit_ = 0;   // current bound on a released node's distance from its anchor, edge lengths
    SmoothingResult result_;
    // Per hex as of the last refreshHexStates: its inverse mean ratio and
    // whether a corner or its centre is inverted; per node: moved since.
    std::vector<double> hexImr_;
    std::vector<std::uint8_t> hexInverted_, nodeMoved_;
    bool hexStatesReady_ = false;
};

void Smoother::refreshHexStates() {
    const std::size_t H = mesh_.hexCount(), N = mesh_.nodeCount();
    auto evaluate = [&](std::size_t h) {
        const HexCoords x = hexCoords(mesh_, static_cast<Index>(h));
        hexImr_[h] = inverseMeanRatio(x);
        hexInverted_[h] = !(minJacobianDeterminant(x) > 0);
    };
    std::vector<std::uint8_t> dirty;
    if (!hexStatesReady_) {
        hexImr_.resize(H);
        hexInverted_.resize(H);
        dirty.assign(H, 1);
        hexStatesReady_ = true;
    } else {
        dirty.assign(H, 0);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, N, kBlock), [&](const auto& r) {
            for (std::size_t v = r.begin(); v != r.end(); ++v)
                if (nodeMoved_[v])
                    for (const Index* h = topo_.nodeHexes.begin(v); h != topo_.nodeHexes.end(v); ++h)
                        raise(dirty[static_cast<std::size_t>(*h)]);
        });
    }
    std::fill(nodeMoved_.begin(), nodeMoved_.end(), std::uint8_t{0});
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H, kBlock), [&](const auto& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h)
            if (dirty[h]) evaluate(h);
    });
}

void Smoother::setUp() {
    mesh_.checkConsistent("mesh to smooth");
    const std::size_t N = mesh_.nodeCount();
    if (&topo_ == &ownTopology_) ownTopology_ = buildTopology(mesh_);
    else requireTopologyOf(mesh_, topo_, "smoothing");
    // Which of mesh.surfaces each boundary/interface quad belongs to (-1:
    // none), for thinning curve bands and for surface nodes' quads.
    std::vector<std::int32_t> quadSurface;
    if (projector_ && !opt_.fixBoundary) {
        quadSurface.assign(topo_.quads.size(), -1);
        for (const SurfacePatch& p : surfacePatches(mesh_, topo_)) {
            std::int32_t id = -1;
            for (std::size_t s = 0; s < mesh_.surfaces.size(); ++s)
                if (mesh_.surfaces[s].inside == p.tag.inside && mesh_.surfaces[s].outside == p.tag.outside)
                    id = static_cast<std::int32_t>(s);
            for (Index q : p.quads) quadSurface[static_cast<std::size_t>(q)] = id;
        }
        if (projector_->hasCurves()) thinCurveBands(quadSurface);
    }

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

    if (anySurface) {
        auto& c = nodeSurfaceQuads_;
        c.offsets.assign(N + 1, 0);
        // Several surfaces may share a material pair (a block's faces and a
        // cut both bound material 1): match quads to a node by the pair.
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
        for (std::size_t q = 0; q < topo_.quads.size(); ++q)
            for (Index v : topo_.quads[q].nodes)
                if (uses(q, v)) c.items[static_cast<std::size_t>(cursor[static_cast<std::size_t>(v)]++)] = static_cast<Index>(q);
    }

    {
        // Curve neighbours: edges joining two curve nodes of the same curve;
        // at the end of a chain (fewer than two), also fixed boundary nodes
        // joined by an edge (the vertex where the curve ends).
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

    buffers_ = std::make_unique<tbb::enumerable_thread_specific<std::vector<CornerTerm>>>(
        [n = maxTerms_] { return std::vector<CornerTerm>(n); });
    everMoved_.assign(N, 0);
    nodeMoved_.assign(N, 0);
    {
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
    touched_.assign(N, 0);
    start_ = mesh_.nodes;
}

Smoother::Visit Smoother::interiorStep(Index v, std::vector<CornerTerm>& buf) const {
    Visit r;
    const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, v, buf.data());
    r.length = localEdgeLength(buf.data(), n);
    NodeObjective<InverseMeanRatio> objective(InverseMeanRatio{}, buf.data(), n);
    r.move = newtonDescent(objective, r.length, opt_.gradientTolerance * static_cast<double>(n) / r.length, opt_.newton);
    r.position = displaced(mesh_.nodes[static_cast<std::size_t>(v)], r.move.displacement);
    return r;
}

Smoother::Visit Smoother::untangleStep(Index v, std::vector<CornerTerm>& buf) const {
    Visit r;
    const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, v, buf.data());
    const double L = r.length = localEdgeLength(buf.data(), n);
    const double beta = opt_.untangleBeta * L * L * L;
    UntangleBeta metric{beta, 0.5 * beta};
    NodeObjective<UntangleBeta> objective(metric, buf.data(), n);
    // Nothing to do where Knupp's measure is already zero.
    if (objective.minDeterminant(Vector3::Zero()) >= beta) return r;
    NewtonOptions newton = opt_.newton;
    newton.maxIterations = 4;
    r.move = newtonDescent(objective, L, 1e-9 * static_cast<double>(n) * beta / L, newton);
    if (r.move.steps == 0) return r;
    // Knupp's measure may trade a deep inversion for a new shallow one; do not
    // let it: shorten the move until every corner that was valid stays valid.
    if (!guarded_) {
        r.position = displaced(mesh_.nodes[static_cast<std::size_t>(v)], r.move.displacement);
        return r;
    }
    const Vector3 full = r.move.displacement;
    Vector3 d = full;
    for (int k = 0; k < 8 && !keepsValidCornersValid(buf.data(), n, full, d); ++k) d *= 0.5;
    if (!keepsValidCornersValid(buf.data(), n, full, d)) {
        r.move.steps = 0;
        return r;
    }
    r.move.displacement = d;
    r.position = displaced(mesh_.nodes[static_cast<std::size_t>(v)], d);
    return r;
}

bool Smoother::surfaceFrame(std::size_t sv, Vector3& centroid, Vector3& normal) const {
    centroid.setZero();
    normal.setZero();
    Vector3 firstNormal = Vector3::Zero();
    double area = 0;
    for (const Index* q = nodeSurfaceQuads_.begin(sv); q != nodeSurfaceQuads_.end(sv); ++q) {
        const auto& qn = topo_.quads[static_cast<std::size_t>(*q)].nodes;
        Vector3 p[4];
        for (int i = 0; i < 4; ++i) {
            const Vec3& y = mesh_.nodes[static_cast<std::size_t>(qn[i])];
            p[i] = Vector3(y[0], y[1], y[2]);
        }
        Vector3 an = (p[2] - p[0]).cross(p[3] - p[1]);  // twice the area vector of the quad
        const double a = 0.5 * an.norm();
        if (firstNormal.isZero()) firstNormal = an;
        else if (an.dot(firstNormal) < 0) an = -an;  // interface quads may face either way
        centroid += a * 0.25 * (p[0] + p[1] + p[2] + p[3]);
        normal += an;
        area += a;
    }
    if (!(area > 0) || !(normal.norm() > 0)) return false;
    centroid /= area;
    normal.normalize();
    return true;
}

// Untangling a surface node: Newton on Knupp's measure within the tangent
// plane, then back onto the surface; kept only if the measure went down.
Smoother::Visit Smoother::untangleSurfaceStep(Index v, std::vector<CornerTerm>& buf) const {
    Visit r;
    const auto sv = static_cast<std::size_t>(v);
    const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, v, buf.data());
    const double L = r.length = localEdgeLength(buf.data(), n);
    const double beta = opt_.untangleBeta * L * L * L;
    NodeObjective<UntangleBeta> objective(UntangleBeta{beta, 0.5 * beta}, buf.data(), n);
    if (objective.minDeterminant(Vector3::Zero()) >= beta) return r;
    Vector3 centroid, normal;
    if (!surfaceFrame(sv, centroid, normal)) return r;
    const double f0 = objective.value(Vector3::Zero());
    TangentPlaneObjective<NodeObjective<UntangleBeta>> tangent(objective, normal);
    NewtonOptions newton = opt_.newton;
    newton.maxIterations = 4;
    const NodeMove m = newtonDescent(tangent, L, 1e-9 * static_cast<double>(n) * beta / L, newton);
    if (m.steps == 0) return r;
    const Matrix3 P = Matrix3::Identity() - normal * normal.transpose();
    const Vector3 moved = P * m.displacement;  // what `objective` is now shifted by
    const Vec3& xv = mesh_.nodes[sv];
    const Vec3 y = projector_->project(mesh_.nodeClass[sv].id, displaced(xv, moved));
    const Vector3 d(y[0] - xv[0], y[1] - xv[1], y[2] - xv[2]);
    if (!d.allFinite()) return r;
    const double f = objective.value(d - moved);
    if (!(f < f0) || (guarded_ && !keepsValidCornersValid(buf.data(), n, moved, d))) return r;
    r.move.before = f0;
    r.move.after = f;
    r.move.displacement = d;
    r.move.steps = 1;
    r.position = y;
    return r;
}

// Centroidal-area smoothing restricted to the tangent plane, then projection
// back onto the surface; a move is taken only if every adjacent corner stays
// positive (and, by default, the node's mean-ratio objective does not rise).
Smoother::Visit Smoother::surfaceStep(Index v, std::vector<CornerTerm>& buf) const {
    Visit r;
    NodeMove& move = r.move;
    const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, v, buf.data());
    const double L = r.length = localEdgeLength(buf.data(), n);
    NodeObjective<InverseMeanRatio> objective(InverseMeanRatio{}, buf.data(), n);
    const double f0 = objective.value(Vector3::Zero());
    move.before = move.after = f0;
    if (!std::isfinite(f0)) return r;

    const auto sv = static_cast<std::size_t>(v);
    const Vec3& xv = mesh_.nodes[sv];
    const Vector3 x(xv[0], xv[1], xv[2]);
    Vector3 centroid, normal;
    if (!surfaceFrame(sv, centroid, normal)) return r;
    Vector3 delta = centroid - x;
    delta -= delta.dot(normal) * normal;
    const std::int32_t surface = mesh_.nodeClass[sv].id;
    if (delta.norm() > opt_.moveTolerance * L) {
        double omega = opt_.surfaceRelaxation;
        for (int k = 0; k <= opt_.surfaceHalvings; ++k, omega *= 0.5) {
            const Vector3 trial = x + omega * delta;
            const Vec3 y = projector_->project(surface, Vec3{trial[0], trial[1], trial[2]});
            const Vector3 d(y[0] - xv[0], y[1] - xv[1], y[2] - xv[2]);
            if (!d.allFinite()) continue;
            const double f = objective.value(d);
            if (!std::isfinite(f) || (opt_.surfaceMustNotWorsen && f > f0)) continue;
            move.displacement = d;
            move.after = f;
            move.steps = 1;
            r.position = y;  // exactly the projector's point
            return r;
        }
    }
    if (!opt_.surfaceNewtonFallback) return r;
    // The centroid is reached or would make the hexes worse: minimise the
    // hexes' mean ratio within the tangent plane instead, then project.
    TangentPlaneObjective<NodeObjective<InverseMeanRatio>> tangent(objective, normal);
    const NodeMove m = newtonDescent(tangent, L, opt_.gradientTolerance * static_cast<double>(n) / L, opt_.newton);
    if (m.steps == 0) return r;
    const Matrix3 P = Matrix3::Identity() - normal * normal.transpose();
    const Vector3 moved = P * m.displacement;  // what `objective` is now shifted by
    const Vec3 y = projector_->project(surface, displaced(xv, moved));
    const Vector3 d(y[0] - xv[0], y[1] - xv[1], y[2] - xv[2]);
    if (!d.allFinite()) return r;
    const double f = objective.value(d - moved);
    if (!std::isfinite(f) || !(f < f0)) return r;
    move.displacement = d;
    move.after = f;
    move.steps = 1;
    r.position = y;
    return r;
}

// Released nodes, one at a time in index order (few, and deterministic):
// the largest step towards their projection, of 1, 1/2, ... 1/64, that keeps
// every corner around them positive.
void Smoother::returnToSurface() {
    auto& buf = buffers_->local();
    for (std::size_t v = 0; v < released_.size(); ++v) {
        if (!released_[v]) continue;
        if (mode_[v] == Mode::Curve && !projector_->hasCurves()) continue;  // nowhere to return to
        const Vec3& x = mesh_.nodes[v];
        const Vec3 y = mode_[v] == Mode::Curve ? projector_->projectToCurve(mesh_.nodeClass[v].id, x)
                                               : projector_->project(mesh_.nodeClass[v].id, x);
        const Vector3 full(y[0] - x[0], y[1] - x[1], y[2] - x[2]);
        if (!full.allFinite()) continue;
        const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, static_cast<Index>(v), buf.data());
        NodeObjective<InverseMeanRatio> objective(InverseMeanRatio{}, buf.data(), n);
        double t = 1.0;
        for (int k = 0; k <= 6; ++k, t *= 0.5)
            if (std::isfinite(objective.value(t * full))) {
                moveNode(v, k == 0 ? y : displaced(x, t * full));
                if (k == 0) released_[v] = 0;
                break;
            }
    }
}

// Curve bands. Extraction marks every cell where three materials meet, and
// where a junction runs diagonally to the grid those cells form a band two
// wide instead of a chain: a surface quad then has three or four nodes of one
// curve. Once they are all on the curve (a line) that quad is flat, with an
// angle near 180 degrees or no area at all, and the hexes on it cannot be
// untangled (JHU labels at 2.5-5 mm). Before smoothing, in each such quad the
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
            for (const Index* h = topo_.nodeHexes.begin(v); h != topo_.nodeHexes.end(v); ++h)
                for (Index f : topo_.hexQuads[static_cast<std::size_t>(*h)]) {
                    const std::int32_t s = quadSurface[static_cast<std::size_t>(f)];
                    const auto& fn = topo_.quads[static_cast<std::size_t>(f)].nodes;
                    if (s >= 0 && std::find(fn.begin(), fn.end(), v) != fn.end() &&
                        std::find(surfaces.begin(), surfaces.end(), s) == surfaces.end())
                        surfaces.push_back(s);
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

Smoother::Visit Smoother::curveStep(Index v, std::vector<CornerTerm>& buf) const {
    Visit r = curveSlide(v, buf);
    if (r.move.steps > 0 || !std::isfinite(r.move.before)) return r;
    // At rest but off the curve (a chain that started beside it, evenly
    // spaced, has nothing to slide towards): onto the curve, as long as the
    // hexes stay valid; the curve comes before a slightly better mean ratio.
    const auto sv = static_cast<std::size_t>(v);
    const Vec3& xv = mesh_.nodes[sv];
    const Vec3 y = projector_->projectToCurve(mesh_.nodeClass[sv].id, xv);
    const Vector3 d(y[0] - xv[0], y[1] - xv[1], y[2] - xv[2]);
    if (!d.allFinite() || !(d.norm() > opt_.moveTolerance * r.length)) return r;
    // gathered again: curveSlide's Newton step leaves the terms shifted
    const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, v, buf.data());
    const double f = NodeObjective<InverseMeanRatio>(InverseMeanRatio{}, buf.data(), n).value(d);
    if (!std::isfinite(f)) return r;
    r.move.displacement = d;
    r.move.after = f;
    r.move.steps = 1;
    r.position = y;
    return r;
}

Smoother::Visit Smoother::curveSlide(Index v, std::vector<CornerTerm>& buf) const {
    Visit r;
    const auto sv = static_cast<std::size_t>(v);
    const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, v, buf.data());
    const double L = r.length = localEdgeLength(buf.data(), n);
    NodeObjective<InverseMeanRatio> objective(InverseMeanRatio{}, buf.data(), n);
    const double f0 = objective.value(Vector3::Zero());
    r.move.before = r.move.after = f0;
    const std::size_t k = nodeCurveNeighbours_.size(sv);
    if (!std::isfinite(f0) || k == 0) return r;
    const Vec3& xv = mesh_.nodes[sv];
    const Vector3 x(xv[0], xv[1], xv[2]);
    Vector3 target = Vector3::Zero();
    for (const Index* u = nodeCurveNeighbours_.begin(sv); u != nodeCurveNeighbours_.end(sv); ++u) {
        const Vec3& p = mesh_.nodes[static_cast<std::size_t>(*u)];
        target += Vector3(p[0], p[1], p[2]);
    }
    const Vector3 delta = target / static_cast<double>(k) - x;
    if (delta.norm() > opt_.moveTolerance * L) {
        double omega = opt_.surfaceRelaxation;
        for (int i = 0; i <= opt_.surfaceHalvings; ++i, omega *= 0.5) {
            const Vec3 y = projector_->projectToCurve(mesh_.nodeClass[sv].id, displaced(xv, omega * delta));
            const Vector3 d(y[0] - xv[0], y[1] - xv[1], y[2] - xv[2]);
            if (!d.allFinite()) continue;
            const double f = objective.value(d);
            if (!std::isfinite(f) || (opt_.surfaceMustNotWorsen && f > f0)) continue;
            r.move.displacement = d;
            r.move.after = f;
            r.move.steps = 1;
            r.position = y;
            return r;
        }
    }
    if (!opt_.surfaceNewtonFallback) return r;
    // As for surface nodes: Newton on the hexes' mean ratio along the curve's
    // tangent (the direction between the two curve neighbours of a chain's
    // inner node, towards the one of its end), then back onto the curve.
    const Index* nb = nodeCurveNeighbours_.begin(sv);
    const Vec3& a = mesh_.nodes[static_cast<std::size_t>(nb[0])];
    const Vec3& b = k >= 2 ? mesh_.nodes[static_cast<std::size_t>(nb[1])] : xv;
    Vector3 t(b[0] - a[0], b[1] - a[1], b[2] - a[2]);
    if (!(t.norm() > 0)) return r;
    t.normalize();
    TangentLineObjective<NodeObjective<InverseMeanRatio>> line(objective, t);
    const NodeMove m = newtonDescent(line, L, opt_.gradientTolerance * static_cast<double>(n) / L, opt_.newton);
    if (m.steps == 0) return r;
    const Vector3 moved = t * t.dot(m.displacement);  // what `objective` is now shifted by
    const Vec3 y = projector_->projectToCurve(mesh_.nodeClass[sv].id, displaced(xv, moved));
    const Vector3 d(y[0] - xv[0], y[1] - xv[1], y[2] - xv[2]);
    if (!d.allFinite()) return r;
    const double f = objective.value(d - moved);
    if (!std::isfinite(f) || !(f < f0)) return r;
    r.move.displacement = d;
    r.move.after = f;
    r.move.steps = 1;
    r.position = y;
    return r;
}

bool Smoother::untangleRound(bool guard, std::size_t before) {
    guarded_ = guard && opt_.untangleKeepsValidCorners;
    const std::vector<Vec3> saved = guarded_ ? std::vector<Vec3>{} : mesh_.nodes;
    untanglePhase();
    guarded_ = opt_.untangleKeepsValidCorners;
    if (saved.empty() || invertedNow() <= before) return true;
    for (std::size_t v = 0; v < saved.size(); ++v)
        if (saved[v] != mesh_.nodes[v]) moveNode(v, saved[v]);
    return false;
}

void Smoother::untanglePhase() {
    const auto t0 = Clock::now();
    const std::size_t N = mesh_.nodeCount(), H = mesh_.hexCount();
    std::size_t count = invertedNow();
    std::vector<std::uint8_t> inverted = hexInverted_;
    std::vector<std::uint8_t> inRegion(N, 0), hexInRegion(H, 0);
    std::vector<Index> regionNodes, regionHexes;  // regionHexes: hexes whose status region nodes can change
    std::vector<std::vector<Index>> lists;
    // The region: movable nodes within `rings` rings of the inverted hexes.
    auto buildRegion = [&](int rings) {
        for (Index v : regionNodes) inRegion[static_cast<std::size_t>(v)] = 0;
        for (Index h : regionHexes) hexInRegion[static_cast<std::size_t>(h)] = 0;
        regionNodes.clear();
        regionHexes.clear();
        auto add = [&](Index u) {
            const Mode m = mode_[static_cast<std::size_t>(u)];
            if (m != Mode::Frozen && (m != Mode::Curve || releaseSurface_) && !inRegion[static_cast<std::size_t>(u)]) {
                inRegion[static_cast<std::size_t>(u)] = 1;
                regionNodes.push_back(u);
            }
        };
        for (std::size_t h = 0; h < H; ++h)
            if (inverted[h])
                for (Index u : mesh_.hexes[h]) add(u);
        std::size_t layerStart = 0;
        for (int ring = 0; ring < rings; ++ring) {
            const std::size_t layerEnd = regionNodes.size();
            for (std::size_t i = layerStart; i < layerEnd; ++i) {
                const auto v = static_cast<std::size_t>(regionNodes[i]);
                for (const Index* h = topo_.nodeHexes.begin(v); h != topo_.nodeHexes.end(v); ++h)
                    for (Index u : mesh_.hexes[static_cast<std::size_t>(*h)]) add(u);
            }
            layerStart = layerEnd;
        }
        lists.assign(colouring_.classes.size(), {});
        for (Index v : regionNodes) {
            lists[static_cast<std::size_t>(colouring_.colour[static_cast<std::size_t>(v)])].push_back(v);
            for (const Index* h = topo_.nodeHexes.begin(v); h != topo_.nodeHexes.end(v); ++h)
                if (!hexInRegion[static_cast<std::size_t>(*h)]) {
                    hexInRegion[static_cast<std::size_t>(*h)] = 1;
                    regionHexes.push_back(*h);
                }
        }
        for (auto& l : lists) std::sort(l.begin(), l.end());
    };

    // An untangling visit is a function of where the nodes of the node's hexes
    // are (the phase's flags, anchors and start positions stay put), so a
    // node whose visit moved nothing, and none of whose hexes' nodes moved
    // since, is `settled` and skipped: the outer rings of a grown region are
    // mostly such nodes. Bit for bit the result without the skip.
    std::vector<std::uint8_t> settled(N, 0);
    auto tryMove = [&](Index v) {
        const auto sv = static_cast<std::size_t>(v);
        const bool onSurface = mode_[sv] == Mode::Surface || mode_[sv] == Mode::Curve;
        const Visit r = onSurface && !releaseSurface_ ? untangleSurfaceStep(v, buffers_->local())
                                                      : untangleStep(v, buffers_->local());
        Vec3 to = r.position;
        if (r.move.steps > 0 && onSurface && releaseSurface_) {
            // A released node stays within releaseLimit_ edge lengths of
            // where it was on the surface: the step is shortened (by
            // halves) until it does. Knupp's measure is convex and the
            // determinants affine along the step, so a shorter step still
            // lowers the measure and keeps valid corners valid.
            const Vec3& a = anchor_[sv];
            const Vec3& x = mesh_.nodes[sv];
            const Vector3 d = r.move.displacement;
            double t = 1;
            for (int k = 0; k <= 6; ++k, t *= 0.5) {
                to = displaced(x, t * d);
                const double dx = to[0] - a[0], dy = to[1] - a[1], dz = to[2] - a[2];
                if (std::sqrt(dx * dx + dy * dy + dz * dz) <= releaseLimit_ * anchorLength_[sv]) break;
            }
            if (t < 1.0 / 64) return false;
        }
        if (r.move.steps > 0) {
            const double cap = opt_.untangleMaxTravel * refLength_[sv];
            auto far = [&](const Vec3& p) {
                const double dx = p[0] - start_[sv][0], dy = p[1] - start_[sv][1], dz = p[2] - start_[sv][2];
                return dx * dx + dy * dy + dz * dz > cap * cap;
            };
            if (far(to)) {
                if (onSurface && !releaseSurface_) return false;
                const Vec3& x = mesh_.nodes[sv];
                const Vector3 d(to[0] - x[0], to[1] - x[1], to[2] - x[2]);
                double t = 0.5;
                for (int k = 0; k < 6 && far(to = displaced(x, t * d)); ++k) t *= 0.5;
                if (far(to)) return false;
            }
            if (onSurface && releaseSurface_) released_[sv] = 1;
            moveNode(sv, to);
            everMoved_[sv] = 1;
            touched_[sv] = 1;
            return true;
        }
        return false;
    };

    std::size_t best = count;
    int stall = 0, rings = 0, polish = 0;
    buildRegion(rings);
    for (int sweep = 0; sweep < opt_.maxUntangleSweeps && (count > 0 || polish < opt_.untanglePolishSweeps); ++sweep) {
        if (count == 0) ++polish;
        bool grown = false;
        sweepColours(lists, [&](Index v) {
            const auto sv = static_cast<std::size_t>(v);
            if (settled[sv]) return;
            if (tryMove(v)) clearAround(mesh_, topo_.nodeHexes, v, settled);  // nodes sharing a hex may move now
            else settled[sv] = 1;
        });
        ++result_.untangleSweeps;
        // Only hexes touching the region can have changed.
        std::atomic<bool> flipped{false};
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, regionHexes.size(), 1024), [&](const auto& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const auto h = static_cast<std::size_t>(regionHexes[i]);
                const std::uint8_t now = !(minJacobianDeterminant(hexCoords(mesh_, regionHexes[i])) > 0);
                if (now != inverted[h]) {
                    inverted[h] = now;
                    flipped.store(true, std::memory_order_relaxed);
                }
            }
        });
        count = static_cast<std::size_t>(std::count(inverted.begin(), inverted.end(), std::uint8_t{1}));
        report("untangle", static_cast<double>(sweep + 1) / opt_.maxUntangleSweeps);
        if (count == 0) continue;  // keep the region: polish it towards det >= beta
        if (count < best) {
            best = count;
            stall = 0;
        } else if (++stall >= 2) {
            // Stuck: give the inverted hexes more room by freeing one more ring.
            if (rings >= opt_.maxUntangleGrowth) break;
            ++rings;
            stall = 0;
            grown = true;
        }
        // The region depends on the inverted hexes and the rings only.
        if (flipped.load() || grown) buildRegion(rings);
    }
    report("untangle", 1.0);
    result_.untangleSeconds += secondsSince(t0);
}

void Smoother::meanRatioPhase(const ObjectiveSum& start, bool onlyTouched) {
    const auto t0 = Clock::now();
    const std::size_t N = mesh_.nodeCount(), H = mesh_.hexCount();
    std::vector<std::uint8_t> active(N, 0), next(N, 0);
    if (onlyTouched) {
        for (std::size_t v = 0; v < N; ++v)
            if (touched_[v]) markNeighbours(static_cast<Index>(v), active, next);
        std::fill(next.begin(), next.end(), std::uint8_t{0});
    } else {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H, kBlock), [&](const auto& r) {
            for (std::size_t h = r.begin(); h != r.end(); ++h)
                if (!(inverseMeanRatio(hexCoords(mesh_, static_cast<Index>(h))) <= 1.0 + opt_.activeThreshold))
                    for (Index u : mesh_.hexes[h]) raise(active[static_cast<std::size_t>(u)]);
        });
    }
    std::fill(touched_.begin(), touched_.end(), std::uint8_t{0});

    double total = 8.0 * start.sum;                        // corner sum, the optimised objective
    const double corners = 8.0 * static_cast<double>(start.finite);
    std::vector<double> gain(N, 0.0);
    result_.converged = false;

    for (int sweep = 0; sweep < opt_.maxSweeps; ++sweep) {
        std::fill(gain.begin(), gain.end(), 0.0);
        std::fill(next.begin(), next.end(), std::uint8_t{0});
        std::atomic<std::size_t> updates{0};
        sweepColours(colouring_.classes, [&](Index v) {
            const auto sv = static_cast<std::size_t>(v);
            if (!active[sv] || (mode_[sv] == Mode::Curve && !projector_->hasCurves())) return;
            auto& buf = buffers_->local();
            const Visit r = mode_[sv] == Mode::Surface ? surfaceStep(v, buf)
                            : mode_[sv] == Mode::Curve ? curveStep(v, buf)
                                                       : interiorStep(v, buf);
            if (r.move.steps == 0) return;
            moveNode(sv, r.position);
            gain[sv] = r.move.before - r.move.after;
            everMoved_[sv] = 1;
            updates.fetch_add(1, std::memory_order_relaxed);
            if (r.move.displacement.norm() > opt_.wakeTolerance * r.length) markNeighbours(v, active, next);
        });
        active.swap(next);
        double improvement = 0;
        for (double g : gain) improvement += g;
        // The running total subtracts the nodes' gains, which count centre
        // frames and corners of hexes that were inverted at the start (not
        // in start.sum), so it drifts low and went negative on ch2bet at
        // 1.25 mm after 12 sweeps, which turned the tolerance off. A corner's
        // inverse mean ratio is at least 1, so the sum is at least `corners`.
        const double before = std::max(total, corners);
        total -= improvement;
        ++result_.sweeps;
        result_.nodeUpdates += updates.load();
        result_.objectiveHistory.push_back(start.finite ? total / corners : 0.0);
        report("optimize", static_cast<double>(sweep + 1) / opt_.maxSweeps);
        if (!(improvement > opt_.relativeTolerance * before) ||
            std::find(active.begin(), active.end(), std::uint8_t{1}) == active.end()) {
            result_.converged = true;
            break;
        }
    }
    report("optimize", 1.0);
    result_.meanRatioSeconds += secondsSince(t0);
}

SmoothingResult Smoother::run(bool meanRatio) {
    const auto t0 = Clock::now();
    setUp();
    result_.setupSeconds = secondsSince(t0);
    {
        const ObjectiveSum s = objectiveNow();
        result_.objectiveBefore = meanOf(s);
        result_.invertedBefore = invertedNow();
    }
    guarded_ = opt_.untangleKeepsValidCorners;
    if (result_.invertedBefore > 0 && opt_.untangle) untanglePhase();
    const ObjectiveSum untangled = objectiveNow();
    result_.objectiveAfterUntangle = meanOf(untangled);
    if (meanRatio && opt_.maxSweeps > 0) meanRatioPhase(untangled);
    else result_.converged = true;
    // The mean-ratio sweeps even out the hexes around what is still inverted,
    // which often leaves the untangler room it did not have: alternate while
    // that helps.
    int stalls = 0;  // rounds in a row that removed no inverted hex
    for (int round = 1; round < opt_.untangleRounds && opt_.untangle; ++round) {
        const std::size_t left = invertedNow();
        if (left == 0) break;
        // Every other round drops the guard that keeps valid corners valid:
        // node by node that guard can lock a tight spot; Knupp's measure
        // summed over the region may still fall by trading one deep inversion
        // for shallow ones that the next guarded round removes. A round that
        // ends with more inverted hexes is undone.
        if (!untangleRound(round % 2 == 1, left)) {
            if (++stalls >= 2) break;
            continue;
        }
        const ObjectiveSum after = objectiveNow();
        if (meanRatio && opt_.maxSweeps > 0) meanRatioPhase(after, true);
        if (invertedNow() < left) stalls = 0;
        else if (++stalls >= 2) break;
    }

    // Last resort: what is still inverted is usually a fold of the surface
    // mesh itself (two sides of a narrow gap within one cell), which no
    // tangential move can open. Validity comes before fidelity: the surface
    // nodes of those hexes may leave the surface to untangle them; the
    // mean-ratio sweeps then pull them back as far as the hexes allow.
    if (opt_.untangle && opt_.releaseSurfaceToUntangle && projector_ && !opt_.fixBoundary &&
        invertedNow() > 0) {
        released_.assign(mesh_.nodeCount(), 0);
        anchor_ = mesh_.nodes;
        // The bound is in edge lengths measured now: with the current length a
        // node next to one that went far could go as far again, and so on.
        anchorLength_.assign(mesh_.nodeCount(), 0.0);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, mesh_.nodeCount(), 1024), [&](const auto& r) {
            auto& buf = buffers_->local();
            for (std::size_t v = r.begin(); v != r.end(); ++v)
                if (mode_[v] == Mode::Surface || mode_[v] == Mode::Curve) {
                    const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, static_cast<Index>(v), buf.data());
                    anchorLength_[v] = localEdgeLength(buf.data(), n);
                }
        });
        releaseSurface_ = true;
        // Guarded first, then (undone if it ends worse) unguarded, each
        // followed by mean-ratio sweeps; pass k lets nodes go k times as far.
        for (int pass = 0; pass < opt_.releasePasses && invertedNow() > 0; ++pass) {
            releaseLimit_ = opt_.releaseDistance * (pass + 1);
            for (const bool guard : {true, false}) {
                const std::size_t left = invertedNow();
                if (left == 0) break;
                untangleRound(guard, left);
            }
            releaseSurface_ = false;
            if (meanRatio && opt_.maxSweeps > 0) meanRatioPhase(objectiveNow(), true);
            releaseSurface_ = true;
        }
        releaseSurface_ = false;
        returnToSurface();
        result_.surfaceNodesReleased =
            static_cast<std::size_t>(std::count(released_.begin(), released_.end(), std::uint8_t{1}));
        anchor_ = {};
        anchorLength_ = {};
    }

    const ObjectiveSum s = objectiveNow();
    result_.objectiveAfter = meanOf(s);
    result_.invertedAfter = invertedNow();
    const std::vector<std::uint8_t>& inverted = hexInverted_;
    for (std::size_t h = 0; h < inverted.size(); ++h) {
        if (!inverted[h]) continue;
        const HexCoords x = hexCoords(mesh_, static_cast<Index>(h));
        TangledHex t;
        t.hex = static_cast<Index>(h);
        for (const Vec3& p : x)
            for (int i = 0; i < 3; ++i) t.centroid[i] += p[i] / 8.0;
        t.minDeterminant = minJacobianDeterminant(x);
        result_.untangleFailures.push_back(t);
    }
    result_.nodesMoved = static_cast<std::size_t>(std::count(everMoved_.begin(), everMoved_.end(), std::uint8_t{1}));
    result_.seconds = secondsSince(t0);
    return result_;
}

}  // namespace

void checkOptions(const SmoothingOptions& o) {
    auto fail = [](const char* name, double value, const char* want) {
        throw Error(std::string("smoothing option ") + name + " is " + std::to_string(value) + "; it must be " + want);
    };
    // Negated comparisons so that NaN fails them too.
    auto atLeast = [&](const char* name, double value, double lo, const char* want) {
        if (!(value >= lo)) fail(name, value, want);
    };
    auto finiteAtLeast = [&](const char* name, double value, double lo, const char* want) {
        if (!(value >= lo && std::isfinite(value))) fail(name, value, want);
    };
    atLeast("maxUntangleSweeps", o.maxUntangleSweeps, 0, "0 or more");
    finiteAtLeast("untangleBeta", o.untangleBeta, 0, "a finite fraction >= 0");
    atLeast("maxUntangleGrowth", o.maxUntangleGrowth, 0, "0 or more");
    atLeast("untanglePolishSweeps", o.untanglePolishSweeps, 0, "0 or more");
    if (!(o.untangleMaxTravel > 0))
        fail("untangleMaxTravel", o.untangleMaxTravel, "a positive number of edge lengths (infinity for no bound)");
    atLeast("untangleRounds", o.untangleRounds, 0, "0 or more");
    finiteAtLeast("releaseDistance", o.releaseDistance, 0, "a finite number of edge lengths >= 0");
    atLeast("releasePasses", o.releasePasses, 0, "0 or more");
    atLeast("maxSweeps", o.maxSweeps, 0, "0 or more");
    finiteAtLeast("relativeTolerance", o.relativeTolerance, 0, "a finite fraction >= 0");
    finiteAtLeast("wakeTolerance", o.wakeTolerance, 0, "a finite fraction >= 0");
    finiteAtLeast("moveTolerance", o.moveTolerance, 0, "a finite fraction >= 0");
    finiteAtLeast("activeThreshold", o.activeThreshold, 0, "a finite number >= 0");
    finiteAtLeast("gradientTolerance", o.gradientTolerance, 0, "a finite number >= 0");
    finiteAtLeast("surfaceRelaxation", o.surfaceRelaxation, 0, "a finite fraction >= 0");
    atLeast("surfaceHalvings", o.surfaceHalvings, 0, "0 or more");
    atLeast("newton.maxIterations", o.newton.maxIterations, 0, "0 or more");
    atLeast("newton.maxHalvings", o.newton.maxHalvings, 0, "0 or more");
    finiteAtLeast("newton.armijo", o.newton.armijo, 0, "a finite fraction >= 0");
    if (!(o.newton.maxStep > 0 && std::isfinite(o.newton.maxStep)))
        fail("newton.maxStep", o.newton.maxStep, "a positive finite number of edge lengths");
    finiteAtLeast("newton.minStep", o.newton.minStep, 0, "a finite number of edge lengths >= 0");
}

SmoothingResult optimizeMesh(HexMesh& mesh, const SurfaceProjector* projector, const SmoothingOptions& options,
                             const Progress& progress, const Topology* topology) {
    checkOptions(options);
    return Smoother(mesh, projector, options, progress, topology).run(true);
}

SmoothingResult untangle(HexMesh& mesh, const SmoothingOptions& options, const Progress& progress) {
    checkOptions(options);
    return Smoother(mesh, nullptr, options, progress, nullptr).run(false);
}

double meanObjective(const HexMesh& mesh, std::size_t* inverted) {
    const ObjectiveSum s = objectiveSum(mesh);
    if (inverted) *inverted = invertedCount(mesh);
    return meanOf(s);
}

}  // namespace isohex::smoothing

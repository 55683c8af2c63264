#pragma once
// Internal to smoothing/: the whole-mesh smoother behind optimizeMesh and
// untangle, as named phases over its state. Optimize.cpp runs the phases
// (untangle, mean ratio, release) and keeps the whole-mesh figures;
// SmootherSetUp.cpp prepares the per-node data; Untangle.cpp holds the
// untangling phase; NodeSteps.cpp the moves of one node.
#include <algorithm>
#include <cmath>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string_view>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Parallel.hpp"
#include "isohex/core/Progress.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/Colouring.hpp"
#include "isohex/smoothing/NodeObjective.hpp"
#include "isohex/smoothing/Optimize.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::smoothing::detail {

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

// The sum over hexes 0..H-1 of q(h) where it is finite, in fixed blocks
// (core's blockReduce: the same floating-point result for any thread count).
template <class Q>
inline ObjectiveSum blockSum(std::size_t H, Q q) {
    return parallel::blockReduce<ObjectiveSum>(
        H, kBlock,
        [&](ObjectiveSum& s, std::size_t h) {
            const double v = q(h);
            if (std::isfinite(v)) {
                s.sum += v;
                ++s.finite;
            }
        },
        [](ObjectiveSum& total, const ObjectiveSum& s) {
            total.sum += s.sum;
            total.finite += s.finite;
        });
}

inline double meanOf(const ObjectiveSum& s) { return s.finite ? s.sum / static_cast<double>(s.finite) : 0.0; }

inline void raise(std::uint8_t& flag) { std::atomic_ref<std::uint8_t>(flag).store(1, std::memory_order_relaxed); }

// The region an untangling phase works on: the movable nodes within some
// rings of the inverted hexes, per colour in increasing order, and the hexes
// whose status those nodes can change.
// Where the nodes an untangling round moves were before it, each logged at
// its first move (a node is visited by one thread at a time); the order of the
// entries does not matter, since undoing puts every node back.
struct UndoLog {
    explicit UndoLog(std::size_t nodes) : logged(nodes, 0) {}
    std::vector<std::uint8_t> logged;  // per node
    tbb::enumerable_thread_specific<std::vector<std::pair<Index, Vec3>>> entries;
};

struct UntangleRegion {
    std::vector<std::uint8_t> inRegion, hexInRegion;  // per node, per hex
    std::vector<Index> nodes, hexes;
    std::vector<std::vector<Index>> lists;  // per colour
};

class Smoother {
public:
    Smoother(HexMesh& mesh, const SurfaceProjector* projector, const SmoothingOptions& opt, const Progress& progress,
             const Topology* topology)
        : mesh_(mesh), projector_(projector), opt_(opt), progress_(progress),
          topo_(topology ? *topology : ownTopology_) {}

    SmoothingResult run(bool meanRatio);

private:
    // --- set-up (SmootherSetUp.cpp), in the order setUp() runs them
    void setUp();
    // Which of mesh.surfaces each boundary/interface quad belongs to (-1:
    // none), for thinning curve bands and for surface nodes' quads; empty
    // when surface nodes do not move.
    std::vector<std::int32_t> quadSurfaces() const;
    void thinCurveBands(const std::vector<std::int32_t>& quadSurface);
    // How each node may move (mode_); true if some node slides on a surface.
    bool assignModes();
    // Colours the movable nodes and sizes the corner-term buffers.
    void colourMovable();
    // nodeSurfaceQuads_: per surface node, the quads of its own surface.
    void buildSurfaceQuads(const std::vector<std::int32_t>& quadSurface);
    // nodeCurveNeighbours_: per curve node, its neighbours along the curve.
    void buildCurveNeighbours();
    // refLength_: the mean edge length at each node at the start.
    void measureReferenceLengths();

    // --- the phases (Optimize.cpp)
    // Untangle / mean-ratio rounds while they remove inverted hexes.
    void alternateRounds(bool meanRatio);
    // Last resort: surface nodes of hexes still inverted leave their surface to untangle them.
    void releasePhase(bool meanRatio);
    // The release's bounds: anchors and their edge lengths.
    void anchorReleasedNodes();
    void returnToSurface();
    // With `onlyTouched`, only nodes that untangling moved since the last
    // mean-ratio phase (and their neighbours) start active: the rest is
    // where the previous phase left it.
    void meanRatioPhase(const ObjectiveSum& start, bool onlyTouched = false);
    // The nodes a mean-ratio phase starts with.
    std::vector<std::uint8_t> initialActive(bool onlyTouched, std::vector<std::uint8_t>& next);
    // The figures after, and the hexes still inverted.
    void finish();

    // --- untangling (Untangle.cpp)
    void untanglePhase();
    // One untangling phase, with the valid-corner guard or without it; a phase
    // without it that ends with more than `before` inverted hexes is undone
    // (returns false then).
    bool untangleRound(bool guard, std::size_t before);
    // The region: movable nodes within `rings` rings of the inverted hexes.
    void buildRegion(UntangleRegion& region, int rings, const std::vector<std::uint8_t>& inverted) const;
    // One untangling visit of node v; true if it moved.
    bool untangleMove(Index v);
    // A released node's step shortened (by halves) until it stays within
    // releaseLimit_ edge lengths of its anchor; false if it cannot.
    bool withinRelease(std::size_t sv, const Vector3& d, Vec3& to) const;
    // A step shortened until the node stays within untangleMaxTravel of its
    // start; false if it cannot (or is a surface node on its surface).
    bool withinTravel(std::size_t sv, bool onSurface, Vec3& to) const;
    // The region's hexes' inverted flags brought up to date; true if one changed.
    bool refreshInverted(const UntangleRegion& region, std::vector<std::uint8_t>& inverted) const;

    // --- the moves of one node (NodeSteps.cpp)
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
    static Vector3 offset(const Vec3& y, const Vec3& x) { return Vector3(y[0] - x[0], y[1] - x[1], y[2] - x[2]); }
    // Gathers node v's corner terms into buf and sets r.length to its local
    // edge length; returns the number of terms.
    std::size_t gatherTerms(Index v, std::vector<CornerTerm>& buf, Visit& r) const {
        const std::size_t n = gatherCornerTerms(mesh_, topo_.nodeHexes, v, buf.data());
        r.length = localEdgeLength(buf.data(), n);
        return n;
    }
    // The end of a Newton move within a tangent plane or line, by `moved`
    // (what `objective` is shifted by after it): the node goes to y, the
    // projector's point for where the move took it, if the objective there
    // is finite and below f0.
    template <class Objective>
    static void acceptProjected(Visit& r, Objective& objective, const Vec3& x, const Vector3& moved, const Vec3& y,
                                double f0) {
        const Vector3 d = offset(y, x);
        if (!d.allFinite()) return;
        const double f = objective.value(d - moved);
        if (!std::isfinite(f) || !(f < f0)) return;
        accept(r, d, f, y);
    }
    // A visit that moves the node to y, by d, with objective f.
    static void accept(Visit& r, const Vector3& d, double f, const Vec3& y) {
        r.move.displacement = d;
        r.move.after = f;
        r.move.steps = 1;
        r.position = y;
    }
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
        if (undo_ && std::atomic_ref<std::uint8_t>(undo_->logged[v]).exchange(1, std::memory_order_relaxed) == 0)
            undo_->entries.local().emplace_back(static_cast<Index>(v), mesh_.nodes[v]);
        mesh_.nodes[v] = p;
        nodeMoved_[v] = 1;
    }
    // Brings hexImr_ and hexInverted_ up to date: on the first call every
    // hex, after that only the hexes of nodes moved since the last call.
    void refreshHexStates();
    // Whole-mesh figures between phases (dozens of them on a large mesh,
    // each a pass over every hex when evaluated again), the same values a full
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

    Topology ownTopology_;  // built in setUp when the caller gave none; only nodeHexes kept after it
    const Topology& topo_;  // the caller's topology of mesh_, or ownTopology_
    std::vector<Mode> mode_;
    NodeColouring colouring_;
    Csr nodeSurfaceQuads_;  // per node, the surface quads of its own surface (Surface nodes only), as slots of
    std::vector<std::array<Index, 4>> surfaceQuadNodes_;  // the nodes of each quad some row names
    Csr nodeCurveNeighbours_;  // per Curve node, the nodes joined to it by an edge of the same curve
    std::size_t maxTerms_ = 0;
    std::unique_ptr<tbb::enumerable_thread_specific<std::vector<CornerTerm>>> buffers_;
    std::vector<std::uint8_t> everMoved_;
    // Where each node started and the mean length of its edges there: no
    // untangling move takes a node farther than untangleMaxTravel of those
    // lengths from its start. Knupp's target (beta ~ L^3) grows with the
    // edges a node stretches, so without a bound a node could chase it across
    // the mesh (surface nodes ended dozens of elements from where they started).
    std::vector<double> refLength_;
    std::vector<Vec3> start_;
    std::vector<std::uint8_t> touched_;  // moved by untangling since the last mean-ratio phase
    bool guarded_ = true;  // untangling moves may not invert a valid corner
    std::unique_ptr<UndoLog> undo_;  // while an unguarded round runs
    bool releaseSurface_ = false;  // surface nodes untangle in 3-D, off their surface
    std::vector<std::uint8_t> released_;
    // Per surface or curve node (anchorNodes_, in increasing order): its
    // position when the release began and its local edge length there and then.
    std::vector<Index> anchorNodes_;
    std::vector<Vec3> anchor_;
    std::vector<double> anchorLength_;
    double releaseLimit_ = 0;   // current bound on a released node's distance from its anchor, edge lengths
    SmoothingResult result_;
    // Per hex as of the last refreshHexStates: its inverse mean ratio and
    // whether a corner or its centre is inverted; per node: moved since.
    std::vector<double> hexImr_;
    std::vector<std::uint8_t> hexInverted_, nodeMoved_;
    bool hexStatesReady_ = false;
};

}  // namespace isohex::smoothing::detail

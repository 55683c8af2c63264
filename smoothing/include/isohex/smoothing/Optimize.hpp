#pragma once
// Whole-mesh smoothing: untangle inverted hexes, then minimise the summed
// inverse mean ratio node by node (nonlinear Gauss-Seidel over a graph
// colouring, each colour one parallel loop), sliding surface nodes along their
// surface by centroidal-area smoothing.
//
// Untangling works on the movable nodes of the inverted hexes (Knupp's
// measure with Newton steps; surface nodes within their tangent plane, then
// projected), widening that region ring by ring when it stalls. A node's
// untangling move never makes a corner that was positive non-positive, so the
// number of inverted corners never grows.
//
// Cost per sweep: O(active nodes x their hexes); only nodes near poor hexes,
// or next to a node that moved, are visited, so a grid mesh whose interior is
// cubes pays for its boundary layer only. Memory: O(nodes + hexes) besides the
// topology. Results are bit-identical for any number of threads.
#include <cstdint>
#include <functional>
#include <string_view>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Progress.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/NodeOptimizer.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::smoothing {

struct SmoothingOptions {
    // --- which nodes move
    // Keep every non-interior node where it is (the seed's comparison
    // protocol: only interior nodes move). Otherwise Surface nodes slide on
    // their surface (needs a projector); Curve and Fixed nodes never move.
    bool fixBoundary = false;

    // --- untangling
    bool untangle = true;
    int maxUntangleSweeps = 60;
    // Knupp's beta as a fraction of the cubed local edge length: untangling
    // aims for every corner determinant >= beta, not just > 0.
    double untangleBeta = 0.02;
    // When two sweeps in a row remove no inverted hex, the region (nodes of
    // the inverted hexes) widens by one ring of nodes, at most this many times;
    // after that untangling gives up and the hexes are reported.
    int maxUntangleGrowth = 4;
    // Sweeps over the untangled region after the last inversion is gone, so
    // its corners get from barely positive towards beta before the mean-ratio
    // barrier sees them (which leaves better minima within reach).
    int untanglePolishSweeps = 3;
    // An untangling move may not make a positive corner non-positive (it is
    // shortened until none does). Without this guard Knupp's measure can trade
    // one deep inversion for several shallow ones.
    bool untangleKeepsValidCorners = true;
    // No untangling move takes a node farther than this many of its starting
    // mean edge lengths from where it started (a longer move is shortened by
    // halves, a surface node's is refused). Without it a node could chase
    // Knupp's target, which grows with the edges it stretches, across the
    // mesh (pillow hexes with edges of forty elements were seen).
    double untangleMaxTravel = 2.0;
    // Untangle / mean-ratio rounds: while hexes stay inverted after a round
    // and the last round removed some, untangle again around them.
    int untangleRounds = 4;
    // After the rounds, surface nodes of hexes still inverted may move off
    // their surface (in 3-D, like interior nodes) to untangle them; the
    // mean-ratio sweeps then slide them back towards the surface where the
    // hexes allow. Validity before fidelity; the count is reported.
    bool releaseSurfaceToUntangle = true;
    // How far (in local edge lengths) a released node may go from its place
    // on the surface in the first release pass; pass k allows k times that.
    double releaseDistance = 0.5;
    int releasePasses = 3;

    // --- mean-ratio optimisation
    int maxSweeps = 100;
    // Stop when one sweep lowers the objective (summed over all corners) by
    // less than this fraction of it, as Mesquite does.
    double relativeTolerance = 1e-4;
    // A node is revisited when it or a node sharing a hex moved more than this
    // fraction of its local edge length in its last visit; smaller moves do
    // not wake the neighbours, so the active set stays near the poor hexes.
    // At 0.01 the small moves of the nearly cubic hexes inside kept waking a
    // layer of nodes after another (a million node moves per sweep on a
    // brain scan at 1 mm); 0.05 makes 2.5 to 12 times fewer moves on the
    // bench inputs, for a mean scaled Jacobian at most 0.004 lower.
    double wakeTolerance = 5e-2;
    // A surface or curve node tries its centroidal move only when it is longer
    // than this fraction of its local edge length.
    double moveTolerance = 1e-2;
    // Nodes of hexes whose inverse mean ratio is at most 1 + this start out
    // inactive (cubes are already optimal).
    double activeThreshold = 1e-6;
    // Newton stops at a node when |gradient| x edge length <= this x corners.
    double gradientTolerance = 1e-7;
    NewtonOptions newton;

    // --- surface nodes
    // Fraction of the tangential move towards the area-weighted centroid of the
    // surrounding surface quads tried first; it is halved up to
    // surfaceHalvings times if the move is rejected.
    double surfaceRelaxation = 1.0;
    int surfaceHalvings = 3;
    // Reject a surface move that raises the node's mean-ratio objective (it is
    // always rejected if it would invert a hex), so the objective never rises.
    bool surfaceMustNotWorsen = true;
    // A surface node off its surface (a vertex contouring held back so that
    // no hex starts inverted) takes a valid move onto it even where its hexes
    // get worse: the surface first, as for curve nodes.
    bool offSurfaceNodesOntoSurface = true;
    // Where the centroidal move is rejected or already done, take Newton steps
    // on the node's mean-ratio objective within the tangent plane instead
    // (projected back, kept only if the objective drops): the surface then
    // bends towards what the hexes need, not only towards even quads.
    bool surfaceNewtonFallback = true;
};

// A hex left with a non-positive corner Jacobian.
struct TangledHex {
    Index hex = kNone;
    Vec3 centroid{};             // mean of its 8 nodes
    double minDeterminant = 0;   // smallest corner Jacobian determinant
};

struct SmoothingResult {
    int untangleSweeps = 0;
    int sweeps = 0;                       // mean-ratio sweeps
    std::size_t nodesMoved = 0;           // distinct nodes whose position changed
    std::size_t nodeUpdates = 0;          // accepted node moves, all sweeps
    // Node visits of the mean-ratio sweeps, moved or not (visits - updates
    // = visits that left the node where it was), all sweeps; the surface
    // and curve nodes' share; the visits of each sweep in order.
    std::size_t nodeVisits = 0;
    std::size_t surfaceNodeVisits = 0;
    std::vector<std::size_t> visitHistory;
    // Mean over hexes of the (8-corner averaged) inverse mean ratio, counting
    // only hexes with all corner determinants > 0 (it is infinite for others).
    double objectiveBefore = 0;
    double objectiveAfterUntangle = 0;
    double objectiveAfter = 0;
    std::vector<double> objectiveHistory;  // after each mean-ratio sweep, same measure
    std::size_t invertedBefore = 0;        // hexes with a corner determinant <= 0
    std::size_t invertedAfter = 0;
    std::vector<TangledHex> untangleFailures;  // the hexes still inverted at the end
    std::size_t movableNodes = 0;
    std::size_t curveNodesDemoted = 0;    // curve nodes in a quad with two more of their curve, made surface nodes
    std::size_t surfaceNodesReleased = 0;  // surface nodes the last-resort untangling moved off their surface
    int colours = 0;
    bool converged = false;                // stopped on the tolerance, not on maxSweeps
    double setupSeconds = 0;               // topology, colouring, buffers
    double untangleSeconds = 0;            // all untangling phases
    double meanRatioSeconds = 0;           // all mean-ratio phases
    double seconds = 0;                    // whole call, set-up included
};

// Untangles and optimises `mesh` in place. `projector` may be null, in which
// case Surface nodes stay fixed. Nodes on the mesh boundary that are
// classified Interior never move (classify them with classifyBoundaryNodes to
// let them slide). Throws isohex::Error if an option is out of range
// (checkOptions), mesh arrays disagree or a Surface node names a surface the
// mesh does not have; the mesh is then unchanged. `topology`, if given, must
// be buildTopology(mesh) (smoothing moves nodes only, so it stays valid
// afterwards and the worst-hex pass can reuse it); null builds it here.
SmoothingResult optimizeMesh(HexMesh& mesh, const SurfaceProjector* projector, const SmoothingOptions& options = {},
                             const Progress& progress = {}, const Topology* topology = nullptr);

// Throws isohex::Error naming the option if one is out of range (a negative
// count or tolerance, NaN, a travel bound that is not positive); optimizeMesh
// and untangle call it first, so a bad option never leaves a half-smoothed mesh.
void checkOptions(const SmoothingOptions& options);

// Only the untangling stage of optimizeMesh (no mean-ratio sweeps).
SmoothingResult untangle(HexMesh& mesh, const SmoothingOptions& options = {}, const Progress& progress = {});

// Inverse mean ratio averaged over a hex's 8 corners, averaged over the hexes
// where it is finite, with a deterministic parallel sum; `inverted` (if not
// null) gets the number of hexes with a corner determinant <= 0.
double meanObjective(const HexMesh& mesh, std::size_t* inverted = nullptr);

}  // namespace isohex::smoothing

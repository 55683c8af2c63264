#pragma once
// A finishing pass after the mean-ratio optimiser: raise the worst hexes.
//
// The optimiser minimises a sum over all corners, so a few hexes can stay poor
// where the surface has detail smaller than an element (a spur or pit under a
// surface node: its quads close up like a cone) or where the sheet folds with
// the surface. This pass works, node by node, on the movable nodes of the
// hexes whose scaled Jacobian is below a target, and moves each to where the
// worst hex around it is best: a compass search (interior nodes in 3-D,
// surface nodes in their surface's tangent plane and projected back onto it).
// A trial is better when, in this order, fewer hexes around the node are
// inverted, the smallest scaled Jacobian rises, or it stays and the summed
// squared shortfall below the target drops (several hexes at about the same
// poor value: one node alone cannot lift them all, but it can even them out
// so the next node can). So no hex around a node turns inverted, and none ends
// below the worst value that node's hexes had.
//
// With a surface slack (WorstHexOptions::surfaceSlack), the max-min rounds
// then run once more with surface and curve nodes free in 3-D within that
// distance of their surface or curve, and junction nodes (curve nodes with no
// named curve, where four or more materials meet, fixed otherwise) within it
// of every surface around them: hexes on surface detail finer than an element
// can open only across the surface, and a quad with three or four nodes on
// curves only off them.
//
// It ends with mean rounds: the nodes of the hexes below 0.9 move, along the
// gradient of the summed scaled Jacobian of their hexes, to raise that sum
// while no hex goes below the smaller of its value and the target (the
// optimiser's inverse mean ratio is not the scaled Jacobian, and the sheet
// hexes keep room to rise).
//
// Last of all, surface nodes that are still off their surface (released to
// untangle, or extraction corners held back to keep a hex valid) move back
// towards it as far as the same floors allow. Curve and junction nodes the
// slack rounds moved stay where they are, within the slack.
//
// Each round colours the nodes involved so that nodes of one colour share no
// hex, and moves each colour's nodes in parallel, colours in order: the
// result does not depend on the thread count.
#include <cstddef>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Progress.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/NodeQuality.hpp"  // the helpers the pass shares (declared here before)
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::smoothing {

struct WorstHexOptions {
    // Hexes with a scaled Jacobian below this are worked on (their movable nodes).
    double target = 0.3;
    // Rounds over the nodes of the hexes still below the target.
    int maxRounds = 20;
    // First and last step of the compass search, in local edge lengths.
    double firstStep = 0.25, lastStep = 1.0 / 128.0;
    int maxMovesPerVisit = 40;
    // When the rounds stall with hexes still inverted, their surface nodes
    // may leave the surface by up to this many local edge lengths (0: never).
    double releaseDistance = 0.5;
    // After the release rounds and the joint moves (below), the max-min
    // rounds run again over the nodes of the hexes below the target with
    // surface nodes free in 3-D, off their surface by at most this distance
    // (world units; 0: no such rounds); curve nodes off their curve and
    // junction nodes off each surface around them by as much. The return
    // step (below) runs before them too, so nodes released to untangle get
    // back first. A caller with a fidelity bound (isohex: 0.1 voxel) sets it
    // under that bound.
    double surfaceSlack = 0;
    // Then, for each hex still inverted, the movable nodes within this many
    // rings of it move jointly (surface nodes within releaseDistance of their
    // surface) to maximise a soft minimum of the scaled Jacobians around
    // them; kept only where it helps (0: off). Steps in mean edge lengths,
    // iterations per softness stage (four stages).
    int jointRings = 2;
    double jointStep = 0.01;
    int jointIterations = 400;
    // A hex the joint move leaves inverted gets a second one, from where the
    // first ended, with this many iterations per stage (0: no second move).
    int jointRetryIterations = 2000;
    // A hex still inverted after both gets a third joint move, on a soft
    // minimum of the frames' determinants instead of their scaled Jacobians
    // (iterations per stage; 0: none).
    int jointVolumeIterations = 400;
    // Passes of joint moves: a pass takes the inverted hexes no earlier pass
    // took (a kept move can leave a neighbour of its hex inverted instead).
    int jointPasses = 3;
    // Last, up to meanRounds rounds over the movable nodes of the hexes below
    // meanBelow: each node moves to raise the summed scaled Jacobian of its
    // hexes, where no hex may end below its value before the move, nor below
    // the target if it was above it. A move goes along the gradient of that
    // sum (of each hex's smallest frame; in the tangent plane on a surface,
    // then projected), from meanFirstStep edge lengths, halving the step
    // until the position is better; at most meanMovesPerVisit moves. Curve
    // nodes use the compass search along their curve. Raises the mean;
    // never lowers the minimum below min(minimum before, target) (0 rounds:
    // off).
    int meanRounds = 2;
    double meanBelow = 0.9;
    // With this, the mean rounds move only nodes that share a hex with a
    // node the earlier rounds of this pass moved: a caller that lifts a few
    // hexes (the boundary relaxation) gives back the mean its moves took
    // from their neighbours, without a round over the whole mesh.
    bool meanOnlyNearMoved = false;
    double meanFirstStep = 1.0 / 16.0;
    int meanMovesPerVisit = 8;
    // At the very end, surface nodes farther than returnTolerance local edge
    // lengths from their surface (released to untangle, or held back by
    // extraction and never projected by the optimiser) move back towards
    // it as far as the floors of the mean rounds allow, in up to returnPasses
    // passes (0: off).
    int returnPasses = 3;
    double returnTolerance = 1e-4;
    // The scaled Jacobian does not see edge lengths (its frames are
    // normalised), so the rounds above could pull two nodes almost onto each
    // other without lowering it (on a label atlas: VTK edge ratio up to 1402
    // and condition number up to 1108 after the pass, 12 before it). No move
    // of the compass and gradient rounds leaves an edge at the node shorter
    // than this many local edge lengths, or than the node's shortest edge at
    // the start of the visit if that is shorter (0: no bound; 0.2 was chosen
    // against 0.1 and 0.3).
    double minEdge = 0.2;
    // List the nodes that moved in the result (a caller that measures only
    // what moved then keeps no copy of every node).
    bool listMovedNodes = false;
    // A second threshold the result counts hexes below, before and after
    // (WorstHexResult::reportedBelow*), for a caller that aims above the
    // figure it reports (the boundary relaxation aims 0.01 above Q); 0: none.
    double reportBelow = 0;
};

struct WorstHexResult {
    double minBefore = 0, minAfter = 0;           // smallest scaled Jacobian of the mesh
    std::size_t belowBefore = 0, belowAfter = 0;  // hexes below the target
    std::size_t reportedBelowBefore = 0, reportedBelowAfter = 0;  // below WorstHexOptions::reportBelow
    std::size_t nodesMoved = 0;
    std::size_t surfaceNodesReleased = 0;  // surface nodes left off their surface
    std::size_t jointRegionsTried = 0;     // joint moves made (an inverted hex's region, first or second move)
    std::size_t jointRegionsImproved = 0;  // inverted hexes whose region the joint release improved
    double jointSeconds = 0;               // time in the joint release
    int meanRounds = 0;                    // mean rounds in which a node moved
    double meanGain = 0;                   // mean scaled Jacobian after the mean rounds minus before
    double meanSeconds = 0;                // time in the mean rounds
    int rounds = 0;
    std::size_t surfaceNodesOffBefore = 0;  // movable surface nodes off their surface before the return
    std::size_t surfaceNodesOffAfter = 0;   // ... and after it, farther than surfaceSlack
    std::size_t surfaceNodesWithinSlack = 0;  // left off their surface by at most surfaceSlack
    double returnSeconds = 0;               // time in the return
    std::vector<Index> movedNodes;          // ascending, with WorstHexOptions::listMovedNodes
};

// Surface nodes move only with a projector, Curve nodes only with one that
// knows their curve (3-D trial points projected onto it; never released);
// Fixed nodes and Interior-classified nodes on the mesh boundary never move.
// `topology`, if given, must be buildTopology(mesh); null builds it here.
// `progress` hears "worst_hexes" and the fraction of the pass done.
WorstHexResult raiseWorstHexes(HexMesh& mesh, const SurfaceProjector* projector, const WorstHexOptions& options = {},
                               const Topology* topology = nullptr, const Progress& progress = {});

}  // namespace isohex::smoothing

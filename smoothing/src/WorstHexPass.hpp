#pragma once
// Internal to smoothing/: the worst-hex pass (raiseWorstHexes) as a short
// sequence of named phases over its state. WorstHexes.cpp holds the node
// rounds and the return to the surface; JointRelease.cpp the joint moves.
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/NodePlace.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"
#include "isohex/smoothing/WorstHexes.hpp"
#include "NodeHexes.hpp"

namespace isohex::smoothing::detail {

// Which rounds a node visit belongs to.
struct RoundKind {
    bool release = false;  // surface nodes move in 3-D within releaseDistance of their surface
    bool mean = false;     // the mean rounds: raise the summed scaled Jacobian above the floors
    bool slack = false;    // surface nodes move in 3-D within surfaceSlack of their surface
    int id() const { return 2 * release + mean + 4 * slack; }
};

// The region of an inverted hex h0 for a joint move: its free nodes (movable
// non-curve nodes within some rings of h0) and the hexes around them, both
// sorted. It depends on the connectivity only, not on where the nodes are.
struct Region {
    std::vector<Index> free, hexes;
};

class NodeSearch;

class WorstHexPass {
public:
    WorstHexPass(HexMesh& mesh, const SurfaceProjector* projector, const WorstHexOptions& opt,
                 const Topology* topology, const Progress& progress);
    WorstHexResult run();

private:
    // --- the phases, in the order run() calls them
    // The scaled Jacobians and the figures before; false if there is nothing to do.
    bool measureStart();
    // Topology, per-node flags, compass directions and surface normals.
    void prepare();
    // Rounds of one kind until a round moves nothing (at most maxRounds);
    // the progress goes from `from` to `to` of the pass meanwhile.
    void roundsUntilStill(RoundKind kind, double from, double to);
    // Joint moves of the regions of the hexes still inverted (JointRelease.cpp).
    void jointMoves();
    // Surface nodes still off their surface back towards it; `last` marks and counts what stays off.
    void returnToSurface(bool last);
    // The mean rounds, timed, with the mean gain they make.
    void meanRestore();
    // The figures after.
    void finish();
    // `fraction` of the part of the pass from `from` to `to` done.
    void report(double from, double to, double fraction) const;

    // --- one round of node visits
    // The movable nodes of the hexes the round works on.
    std::vector<std::uint8_t> pickNodes(RoundKind kind) const;
    // Picks, colours and visits the round's nodes; true if one moved.
    bool runRound(RoundKind kind);
    // One node's search (compass or gradient); true if it moved.
    bool visit(Index v, RoundKind kind);
    // The trial directions of a compass search at node sv.
    std::vector<Vec3> compassDirections(std::size_t sv, bool onSurface, bool mean) const;
    // Steps along the gradient of the summed scaled Jacobian (the mean rounds).
    void ascendSteps(NodeSearch& s);
    // Compass steps: the best of the directions, halving the step when none is better.
    void compassSteps(NodeSearch& s, const std::vector<Vec3>& dirs);

    // --- the return to the surface
    // Movable surface nodes farther than returnTolerance edge lengths off
    // their surface; `off` gets each surface node's distance.
    std::vector<Index> offSurfaceNodes(std::vector<double>& off) const;
    // One pass over the candidates in index order, each moved as far back as
    // its hexes' floors allow; true if one got closer.
    bool returnPass(const std::vector<Index>& candidates);
    // The candidates still off after a pass (`off` updated); the others are
    // no longer released.
    std::vector<Index> stillOff(const std::vector<Index>& candidates, std::vector<double>& off);
    // Marks and counts what stays off at the end.
    void countLeftOff(const std::vector<Index>& candidates, const std::vector<double>& off);
    // offBy at the node's position, 0 where the projection fails.
    double distanceOff(std::size_t v) const;

    // --- shared by the phases
    bool movable(Index v) const;
    // Whether node v may move in 3-D in the slack rounds: a surface node of a
    // surface the projector finds, a curve node, or a junction node.
    bool freeInSlack(std::size_t v) const;
    // How far p is from where node v belongs: its surface, its curve, or for a
    // junction node the farthest of the surfaces around it (NaN where a
    // projection fails).
    double offBy(std::size_t v, const Vec3& p) const;
    // Whether p is within bounds[i] of each place i of node v (distancesFromPlace).
    bool withinBounds(Index v, const Vec3& p, const std::vector<double>& bounds) const;
    // junctions_, from the mesh's surface quads.
    void findJunctions();
    // The least each hex around a node may end with in the mean rounds and the return.
    std::vector<double> floorsOf(const NodeHexes& nh) const;
    // After node v moved: its hexes' entries of sj_.
    void refreshAround(std::size_t v);
    // nearMoved_ from everMoved_.
    void markNearMoved();
    std::size_t countBelow(double threshold) const;

    // --- the joint moves (JointRelease.cpp)
    Region regionOf(Index h0, int rings) const;
    // One joint move of a region; true if the region got better.
    bool jointRelease(const Region& region, int iterations, bool byVolume);
    struct JointCounts {
        std::atomic<std::size_t> tried{0}, improved{0};
    };
    // The joint moves one inverted hex gets, each while it is still inverted.
    void jointAttempts(Index h0, const Region& region, JointCounts& counts);
    // Of the pending hexes, in order, those whose region shares no hex with
    // the region of any pending hex before them: they can move in parallel.
    std::vector<std::size_t> independentBatch(const std::vector<std::pair<Index, Region>>& pending,
                                              std::vector<std::uint8_t>& claimed) const;

    HexMesh& mesh_;
    const SurfaceProjector* projector_;
    const WorstHexOptions& opt_;
    const Topology* givenTopology_;
    const Progress& progress_;
    Topology ownTopology_;
    const Topology* topo_ = nullptr;
    WorstHexResult res_;
    std::size_t N_ = 0;
    std::vector<double> sj_;  // usable scaled Jacobian per hex, kept current
    // The worst hex when the mean rounds start (meanRestore); from then on a
    // floor above the target where it is higher (floorsOf).
    double meanFloor_ = 0;
    bool meanRounds_ = false;  // the mean rounds have work (a hex below meanBelow)
    std::vector<std::uint8_t> everMoved_, released_;
    // With meanOnlyNearMoved: the nodes the mean rounds may move (those
    // sharing a hex with a node moved before them); empty otherwise.
    std::vector<std::uint8_t> nearMoved_;
    // A compass visit is a function of where the nodes of the node's hexes
    // are (and of fixed data: its normal, the target, the projector), so a
    // node whose last visit in the same kind of round moved nothing, and none
    // of whose hexes' nodes moved since, would move nothing again: `settled_`
    // marks such nodes and the rounds skip them. Rounds still pick and colour
    // their nodes as before, so the result is the one without the skip, bit
    // for bit. Cleared when the kind of round changes and after the joint
    // release, which moves nodes outside the rounds.
    std::vector<std::uint8_t> settled_;
    int settledKind_ = -1;
    // Directions of the compass search in 3-D: the 6 axes and 8 cube diagonals.
    std::vector<Vec3> dirs3_;
    // Tangent planes from the surfaces as they are at the start (the nodes
    // move by fractions of an element).
    std::vector<Vec3> normal_;
    // The junction nodes and their surfaces (none of a surface the
    // projector does not find), with a surface slack.
    JunctionSurfaces junctions_;
};

}  // namespace isohex::smoothing::detail

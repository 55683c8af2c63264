#pragma once
// Two finishing steps for a mesh whose boundary was captured by sheet
// insertion, run after the mean-ratio optimiser (smoothing::optimizeMesh):
//
//  * raiseWorstHexes: the optimiser minimises a sum, so a few hexes can stay
//    poor where the triangles have detail smaller than an element (a spur or
//    pit under a surface node: its quads close up like a cone). This pass
//    maximises, node by node, the smallest scaled Jacobian of the node's hexes
//    (a compass search: interior nodes in 3-D, surface nodes in their tangent
//    plane and projected back onto their surface), only around hexes below a
//    target. A move is kept if that smallest value rises, or stays and the
//    summed squared shortfall below the target drops; so no hex ends below
//    the worst value the node's hexes had.
//
//  * fitSurfaceVolume: boundary quads whose corners lie on the triangles are
//    chords: on a convex surface they cut inside it, and the mesh loses volume
//    in proportion to (element size / radius of curvature)^2 (-1.8 % on knot1
//    at its mean edge length). This moves each surface node along its normal
//    until the quads around it have, on average, as much of their area outside
//    the triangles as inside (a volume-balanced fit instead of interpolation):
//    the node goes off the triangles by about two thirds of the chord's depth,
//    which also lowers the largest distance of the boundary from the triangles
//    (the middle of a chord was off by the whole depth).
//
// Both are sequential over few nodes, in index order, so the result does not
// depend on the thread count.
#include <cstddef>
#include <cstdint>

#include "isohex/core/HexMesh.hpp"
#include "isohex/sheets/TriangleTree.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::sheets {

struct WorstHexOptions {
    // Hexes with a scaled Jacobian below this are worked on (their movable nodes).
    double target = 0.3;
    // Rounds over the nodes of the hexes still below the target.
    int maxRounds = 20;
    // First and last step of the compass search, in local edge lengths.
    double firstStep = 0.25, lastStep = 1.0 / 128.0;
    int maxMovesPerVisit = 40;
};

struct WorstHexResult {
    double minBefore = 0, minAfter = 0;     // smallest scaled Jacobian of the mesh
    std::size_t belowBefore = 0, belowAfter = 0;  // hexes below the target
    std::size_t nodesMoved = 0;
    int rounds = 0;
};

// Surface nodes move only with a projector; Curve and Fixed nodes, and
// Interior-classified nodes on the mesh boundary, never move.
WorstHexResult raiseWorstHexes(HexMesh& mesh, const smoothing::SurfaceProjector* projector,
                               const WorstHexOptions& options = {});

struct VolumeFitOptions {
    int iterations = 4;
    // A node's offset is halved (at most three times, then dropped) until the
    // smallest scaled Jacobian of its hexes is at least the smaller of its
    // value before and this.
    double keepScaledJacobian = 0.3;
    // Largest offset, in local edge lengths.
    double maxOffset = 0.1;
};

struct VolumeFitResult {
    std::size_t nodes = 0;          // surface nodes considered
    std::size_t nodesMoved = 0;
    std::size_t nodesHeldBack = 0;  // offset shortened or dropped by the quality guard
    double maxOffset = 0;           // largest distance a node moved
    double volumeBefore = 0, volumeAfter = 0;
};

// Moves the Surface nodes of surface `surfaceId` (an index into
// HexMesh::surfaces) that lie on boundary quads of the mesh; `triangles` is
// that surface.
VolumeFitResult fitSurfaceVolume(HexMesh& mesh, const TriangleTree& triangles, std::int32_t surfaceId,
                                 const VolumeFitOptions& options = {});

}  // namespace isohex::sheets

#pragma once
// The volume-balanced fit of the surface nodes: the finishing step for a mesh
// whose boundary was captured by sheet insertion, run after the mean-ratio
// optimiser and smoothing::raiseWorstHexes.
//
// Boundary quads whose corners lie on the triangles are chords: on a convex
// surface they cut inside it, and the mesh loses volume in proportion to
// (element size / radius of curvature)^2. fitSurfaceVolume moves each surface
// node along its normal until the quads around it have, on average, as much
// of their area outside the triangles as inside (a volume-balanced fit
// instead of interpolation): the node goes off the triangles by about two
// thirds of the chord's depth, which also lowers the largest distance of the
// boundary from the triangles (the middle of a chord was off by the whole
// depth).
//
// The gaps are measured in parallel over quads (each written once); offsets
// are updated and applied sequentially over the surface nodes, in index
// order, so the result does not depend on the thread count.
#include <cstddef>
#include <cstdint>

#include "isohex/core/HexMesh.hpp"
#include "isohex/insertion/TriangleTree.hpp"

namespace isohex::insertion {

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

}  // namespace isohex::insertion

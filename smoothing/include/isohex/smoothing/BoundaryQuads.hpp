#pragma once
// The seed's protocol for comparing meshes with the boundary fixed (chapter
// 5): before the boundary nodes are fixed, the boundary quadrilaterals are
// smoothed on the isosurface (the seed's meshes had their boundary improved
// by geometric flow), so that the comparison measures the interior's hexes,
// not the extraction's raw quads. Each surface node moves, in node order
// (deterministic), towards the mean of the centres of its surface quads and
// is projected back onto its surface; a move that would invert a hex around
// the node, or lower the smallest scaled Jacobian there below min(its value,
// 0.2), is halved up to three times and then dropped. Curve and fixed nodes
// stay.
#include <cstddef>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::smoothing {

struct BoundaryQuadResult {
    int sweeps = 0;
    std::size_t moves = 0;  // node moves accepted over all sweeps
    double seconds = 0;
};

// `topology`: buildTopology(mesh) (nodes move only, so it stays valid).
BoundaryQuadResult smoothBoundaryQuads(HexMesh& mesh, const SurfaceProjector& projector, const Topology& topology,
                                       int sweeps = 10);

}  // namespace isohex::smoothing

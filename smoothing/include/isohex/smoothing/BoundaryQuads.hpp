#pragma once
// The seed's protocol for comparing meshes with the boundary fixed (chapter
// 5): before the boundary nodes are fixed, the boundary quadrilaterals are
// smoothed on the isosurface (the seed's meshes had their boundary improved
// by geometric flow, whose tangential step improves the quads' aspect
// ratio), so that the comparison measures the interior's hexes, not the
// extraction's raw quads. The quads alone decide: each surface node moves on
// its surface to lower the 2-D condition number of the quad corners it
// shapes (measured against the surface normal there, so a folded corner is
// the worst), plus that of every corner at it and at the nodes it shares an
// edge with, measured against the mean corner normal of that node (the
// direction a pillow sheet's copy of the node takes: a node whose quads fan
// out across a fold leaves every sheet hex there poor however good each
// quad's angles), by a compass search (the centre of its quads and four tangent
// steps, each projected back onto the surface), in node order
// (deterministic), for a fixed number of sweeps (or until no node moves;
// the compass search keeps finding small gains, so the count decides). The hexes are not looked at: the surface
// mesh is a property of the extraction, shared by every mesh made from it.
// Curve and fixed nodes stay. A surface node off its surface (a vertex
// contouring held back) goes onto it in the first sweep whatever the cost.
#include <cstddef>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::smoothing {

struct BoundaryQuadResult {
    int sweeps = 0;
    std::size_t moves = 0;        // node moves accepted over all sweeps
    std::size_t ontoSurface = 0;  // of those, nodes that were off their surface
    double seconds = 0;
};

struct BoundaryQuadOptions {
    int sweeps = 20;
};

// `topology`: buildTopology(mesh) (nodes move only, so it stays valid).
BoundaryQuadResult smoothBoundaryQuads(HexMesh& mesh, const SurfaceProjector& projector, const Topology& topology,
                                       const BoundaryQuadOptions& options = {});

}  // namespace isohex::smoothing

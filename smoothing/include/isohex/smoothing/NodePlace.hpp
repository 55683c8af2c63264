#pragma once
// Where a node of the boundary belongs, and how far a point is from it: a
// surface node on its surface, a curve node on its curve (where three
// materials meet), and a junction node, a curve node with no named curve
// (NodeClass id -1: where four or more materials meet, or two curves pass
// through one cell), near every surface of the quads around it.
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::smoothing {

// The junction nodes of a mesh, each with the surfaces (ids into
// HexMesh::surfaces) of the boundary and interface quads it is a corner of.
struct JunctionSurfaces {
    std::vector<Index> nodes;                         // ascending
    std::vector<std::vector<std::int32_t>> surfaces;  // per node, ascending
    // The surfaces around node v, or null if v is not a junction node.
    const std::vector<std::int32_t>* of(Index v) const;
};

// Input: a mesh and its topology (any TopologyParts: each has the boundary
// and interface quads). Output: its junction nodes and their surfaces (a
// node next to a surface HexMesh::surfaces does not name gets none); empty,
// without a pass over the quads, if it has none.
JunctionSurfaces junctionSurfaces(const HexMesh& mesh, const Topology& topo);
// The same for a mesh without a topology at hand: one with its boundary and
// interface quads (TopologyParts::Surfaces) is built only if it has junction
// nodes, and freed before the answer.
JunctionSurfaces junctionSurfaces(const HexMesh& mesh);

// How far p is from each place node v belongs to: one distance for a surface
// or curve node (from its surface or curve), one per surface for a junction
// node (in the order of junctions.of(v)), none for an interior or fixed node
// or a junction node with no surfaces listed. NaN where a projection fails.
std::vector<double> distancesFromPlace(const HexMesh& mesh, const SurfaceProjector& projector,
                                       const JunctionSurfaces& junctions, Index v, const Vec3& p);
// The largest of them: 0 for an interior or fixed node, NaN where a
// projection fails or for a junction node with no surfaces listed.
double distanceFromPlace(const HexMesh& mesh, const SurfaceProjector& projector, const JunctionSurfaces& junctions,
                         Index v, const Vec3& p);

}  // namespace isohex::smoothing

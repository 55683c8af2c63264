#pragma once
// The quality of the hexes around one node, and the local geometry a node's
// move is measured in: what the worst-hex pass maximises, shared with other
// finishing steps (sheets' volume fit).
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"

namespace isohex::smoothing {

// Scaled Jacobian for maximising: Verdict's value for a collapsed hex (1e30)
// counts as the worst (-2).
double usableScaledJacobian(const HexCoords& x);

// Smallest usable scaled Jacobian of the hexes around node v with v at p.
double minScaledJacobianAround(const HexMesh& mesh, const Topology& topo, Index v, const Vec3& p);

// Gradient, with respect to node v's position at p, of the summed usable
// scaled Jacobian of v's hexes (each hex's smallest frame: its gradient when
// v enters that frame, else nothing), as the mean rounds step along it.
Vec3 summedScaledJacobianGradient(const HexMesh& mesh, const Topology& topo, Index v, const Vec3& p);

// Mean length of the hex edges at v.
double meanEdgeLengthAt(const HexMesh& mesh, const Topology& topo, Index v);

// Unit normal per node of the mesh's surfaces (boundary quads, and quads
// between two materials oriented from the lower material number to the
// higher), summed area vectors; zero for nodes on no such quad.
std::vector<Vec3> surfaceNormals(const HexMesh& mesh, const Topology& topo);

}  // namespace isohex::smoothing

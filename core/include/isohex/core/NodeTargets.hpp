#pragma once
// Moving nodes towards target positions without inverting a hex: a mesh
// that starts valid with some nodes held back from where they belong (dual
// contouring's vertices held back from the surface) takes each of them as
// far towards its target as the hexes around it allow.
#include <cstddef>
#include <span>

#include "isohex/core/HexMesh.hpp"

namespace isohex {

struct TargetsResult {
    std::size_t reached = 0;  // nodes now at their target exactly
    std::size_t partway = 0;  // moved, but not all the way
    std::size_t stayed = 0;   // not moved at all
};

// Moves nodes[i] towards targets[i] by the largest fraction of 1, 1/2, ...,
// 2^-halvings of the remaining way that leaves every hex around it with
// positive corner and centre Jacobians (core's minJacobianDeterminant), node
// by node in the order given, for up to `passes` passes (a node's move can
// give its neighbour room). A hex that was not valid before is not judged:
// no move makes a valid hex invalid. Sequential, so the result is the same
// for any thread count; the node -> hex rows are built in parallel. Throws
// isohex::Error if the spans differ in length or a node is out of range.
TargetsResult moveTowardsTargets(HexMesh& mesh, std::span<const Index> nodes, std::span<const Vec3> targets,
                                 int halvings = 6, int passes = 3);

}  // namespace isohex

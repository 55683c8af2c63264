#pragma once
// Graph colouring of the nodes that may move, for nonlinear Gauss-Seidel in
// parallel: two nodes sharing a hex get different colours, so all nodes of
// one colour can move at once without either seeing the other half-moved.
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"

namespace isohex::smoothing {

struct NodeColouring {
    std::vector<std::int32_t> colour;         // per node; -1 for nodes that do not move
    std::vector<std::vector<Index>> classes;  // per colour, its nodes in increasing order
};

// Greedy colouring in increasing node order (deterministic): each movable node
// takes the smallest colour not used by an already coloured node of one of its
// hexes. O(sum over movable nodes of their hexes' sizes). Nodes with
// movable[v] == 0 are neither coloured nor constrain others.
NodeColouring colourNodes(const HexMesh& mesh, const Csr& nodeHexes, const std::vector<std::uint8_t>& movable);

}  // namespace isohex::smoothing

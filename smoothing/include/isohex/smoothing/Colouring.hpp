#pragma once
// Graph colouring of the nodes that may move, for nonlinear Gauss-Seidel in
// parallel: two nodes sharing a hex get different colours, so all nodes of
// one colour can move at once without either seeing the other half-moved.
#include <atomic>
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

// For a node v that moved inside one colour's parallel loop: sets flags[u] to
// 0 for every node u of v's hexes, v included. Two nodes of one colour can
// share such a node, hence the atomic stores.
inline void clearAround(const HexMesh& mesh, const Csr& nodeHexes, Index v, std::vector<std::uint8_t>& flags) {
    const auto sv = static_cast<std::size_t>(v);
    for (const Index* h = nodeHexes.begin(sv); h != nodeHexes.end(sv); ++h)
        for (Index u : mesh.hexes[static_cast<std::size_t>(*h)])
            std::atomic_ref<std::uint8_t>(flags[static_cast<std::size_t>(u)]).store(0, std::memory_order_relaxed);
}

}  // namespace isohex::smoothing

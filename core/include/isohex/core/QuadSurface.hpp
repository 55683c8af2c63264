#pragma once
// Manifoldness of a set of quads (a surface given as quads over mesh nodes).
#include <array>
#include <vector>

#include "isohex/core/HexMesh.hpp"

namespace isohex {

struct ManifoldCheck {
    // Edges (smaller node, larger node) used by the wrong number of quads:
    // more than two, or (for a closed surface) one.
    std::vector<std::array<Index, 2>> badEdges;
    // Nodes whose quads do not form one fan (a disk, or a half-disk where an
    // open surface has its border): the "pinch" where parts touch at a point.
    std::vector<Index> badNodes;
    bool ok() const { return badEdges.empty() && badNodes.empty(); }
};

// Linear time, parallel over nodes; results sorted. `closed`: every edge
// must be in exactly two quads; otherwise one or two.
ManifoldCheck checkManifold(const std::vector<std::array<Index, 4>>& quads, std::size_t nodeCount, bool closed);

// The same with the node -> (quad, corner) rows already built: row v is
// rowItems[rowOffsets[v] .. rowOffsets[v + 1]), the items 4 * quad + corner
// of every corner of a quad at node v, in increasing order.
ManifoldCheck checkManifold(const std::array<Index, 4>* quads, const Index* rowOffsets, const Index* rowItems,
                            std::size_t nodeCount, bool closed);

}  // namespace isohex

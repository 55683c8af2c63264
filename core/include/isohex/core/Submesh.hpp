#pragma once
// The part of a mesh around some free nodes, to work on alone: the hexes
// with a free node, their nodes renumbered in the whole mesh's order. Free
// nodes keep their class; the others become Fixed, so whatever moves nodes
// on the submesh moves only free ones. A free node has every hex it belongs
// to in the submesh, so its neighbourhood (its hexes, its boundary and
// interface quads) is the one it has in the whole mesh. Used by the local
// re-optimisation around grid edits (pipeline/LocalRetry.hpp) and the
// boundary relaxation (pipeline/MinQuality.hpp).
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"

namespace isohex {

struct Submesh {
    HexMesh mesh;               // surfaces and curves as the whole mesh's
    std::vector<Index> from;    // per submesh node, its node in the whole mesh (ascending)
    std::vector<std::uint8_t> free;  // per submesh node, 1 if it was free
};

// The submesh of `mesh` around the nodes flagged in `free` (one flag per
// node): its hexes in the whole mesh's order, its nodes in the whole mesh's
// order. O(hexes + nodes).
Submesh cutOut(const HexMesh& mesh, const std::vector<std::uint8_t>& free);

// Writes the submesh's node positions back into the whole mesh it was cut
// from, and the classes of its free nodes (whatever worked on it may have
// changed them; the other nodes' classes in the submesh are the Fixed
// cutOut gave them).
void putBack(const Submesh& s, HexMesh& mesh);

}  // namespace isohex

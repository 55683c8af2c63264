#include "isohex/core/Submesh.hpp"

#include <algorithm>
#include <utility>

namespace isohex {

Submesh cutOut(const HexMesh& mesh, const std::vector<std::uint8_t>& free) {
    Submesh s;
    // Nodes are numbered in whole-mesh order, so the submesh does not depend
    // on which hex reaches a node first: a first pass marks the nodes taken.
    std::vector<Index> to(mesh.nodeCount(), kNone);
    auto hasFree = [&](const Hex& hex) {
        return std::any_of(hex.begin(), hex.end(), [&](Index v) { return free[static_cast<std::size_t>(v)] != 0; });
    };
    for (const Hex& hex : mesh.hexes)
        if (hasFree(hex))
            for (Index v : hex) to[static_cast<std::size_t>(v)] = 0;
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v) {
        if (to[v] == kNone) continue;
        to[v] = static_cast<Index>(s.from.size());
        s.from.push_back(static_cast<Index>(v));
        s.free.push_back(free[v] != 0 ? 1 : 0);
        s.mesh.addNode(mesh.nodes[v], free[v] ? mesh.nodeClass[v] : NodeClass{NodeKind::Fixed, -1});
    }
    for (std::size_t h = 0; h < mesh.hexCount(); ++h) {
        const Hex& hex = mesh.hexes[h];
        if (!hasFree(hex)) continue;
        Hex out{};
        for (std::size_t c = 0; c < 8; ++c) out[c] = to[static_cast<std::size_t>(hex[c])];
        s.mesh.addHex(out, mesh.material[h]);
    }
    s.mesh.surfaces = mesh.surfaces;
    s.mesh.curves = mesh.curves;
    return s;
}

void putBack(const Submesh& s, HexMesh& mesh) {
    for (std::size_t i = 0; i < s.from.size(); ++i) {
        const auto v = static_cast<std::size_t>(s.from[i]);
        mesh.nodes[v] = s.mesh.nodes[i];
        if (s.free[i]) mesh.nodeClass[v] = s.mesh.nodeClass[i];
    }
}

}  // namespace isohex

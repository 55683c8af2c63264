#include "isohex/smoothing/Colouring.hpp"

#include <algorithm>

namespace isohex::smoothing {

NodeColouring colourNodes(const HexMesh& mesh, const Csr& nodeHexes, const std::vector<std::uint8_t>& movable) {
    const std::size_t N = mesh.nodeCount();
    NodeColouring out;
    out.colour.assign(N, -1);
    // taken[c] == v + 1 while colouring node v means colour c is used nearby.
    std::vector<std::size_t> taken;
    for (std::size_t v = 0; v < N; ++v) {
        if (!movable[v]) continue;
        for (const Index* h = nodeHexes.begin(v); h != nodeHexes.end(v); ++h)
            for (Index u : mesh.hexes[static_cast<std::size_t>(*h)]) {
                const std::int32_t c = out.colour[static_cast<std::size_t>(u)];
                if (c >= 0) taken[static_cast<std::size_t>(c)] = v + 1;
            }
        std::int32_t c = 0;
        while (static_cast<std::size_t>(c) < taken.size() && taken[static_cast<std::size_t>(c)] == v + 1) ++c;
        if (static_cast<std::size_t>(c) == taken.size()) {
            taken.push_back(0);
            out.classes.emplace_back();
        }
        out.colour[v] = c;
        out.classes[static_cast<std::size_t>(c)].push_back(static_cast<Index>(v));
    }
    return out;
}

}  // namespace isohex::smoothing

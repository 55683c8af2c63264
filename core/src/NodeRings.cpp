#include "isohex/core/NodeRings.hpp"

#include <algorithm>
#include <utility>

namespace isohex {

std::vector<std::uint8_t> nodesWithinRings(const HexMesh& mesh, std::vector<std::uint8_t> seeds, int rings) {
    for (int r = 0; r < rings; ++r) {
        std::vector<std::uint8_t> next = seeds;
        for (const Hex& h : mesh.hexes)
            if (std::any_of(h.begin(), h.end(), [&](Index v) { return seeds[static_cast<std::size_t>(v)] != 0; }))
                for (Index v : h) next[static_cast<std::size_t>(v)] = 1;
        seeds = std::move(next);
    }
    return seeds;
}

}  // namespace isohex

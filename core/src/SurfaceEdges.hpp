#pragma once
// Which mesh edges lie in a boundary or interface surface: dicing gives the
// nodes it puts on such an edge the surface's class, and collapsing refuses an
// edge between two nodes of one surface that does not lie in it.
#include <algorithm>
#include <cstdint>
#include <vector>

#include "isohex/core/HexCell.hpp"
#include "isohex/core/Topology.hpp"

namespace isohex::detail {

// Per edge, 1 if it is an edge of a boundary or interface quad.
inline std::vector<std::uint8_t> surfaceEdgeMask(const Topology& topo) {
    std::vector<std::uint8_t> onSurface(topo.edges.size(), 0);
    for (const auto* list : {&topo.boundaryQuads, &topo.interfaceQuads})
        for (Index q : *list) {
            const Quad& quad = topo.quads[q];
            const auto& lf = hexcell::kFaces[quad.localFace[0]];
            for (int e = 0; e < 12; ++e) {
                const auto& le = hexcell::kEdges[e];
                if (std::find(lf.begin(), lf.end(), le[0]) != lf.end() &&
                    std::find(lf.begin(), lf.end(), le[1]) != lf.end())
                    onSurface[topo.hexEdges[quad.hex[0]][e]] = 1;
            }
        }
    return onSurface;
}

}  // namespace isohex::detail

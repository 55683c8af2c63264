#include "isohex/core/HexMesh.hpp"

#include <cmath>
#include <string>

#include "isohex/core/Error.hpp"

namespace isohex {

const char* toString(NodeKind kind) {
    switch (kind) {
        case NodeKind::Interior: return "interior";
        case NodeKind::Surface: return "surface";
        case NodeKind::Curve: return "curve";
        case NodeKind::Fixed: return "fixed";
    }
    return "unknown";
}

std::string surfaceName(const SurfaceTag& tag) {
    if (!tag.name.empty()) return tag.name;
    if (tag.outside < 0) return "boundary_m" + std::to_string(tag.inside);
    return "interface_m" + std::to_string(tag.inside) + "_m" + std::to_string(tag.outside);
}

void HexMesh::checkConsistent(const std::string& what) const {
    if (nodeClass.size() != nodes.size())
        throw Error(what + ": mesh has " + std::to_string(nodes.size()) + " nodes but " +
                    std::to_string(nodeClass.size()) + " node classes");
    if (material.size() != hexes.size())
        throw Error(what + ": mesh has " + std::to_string(hexes.size()) + " hexes but " +
                    std::to_string(material.size()) + " material ids");
    const auto n = static_cast<Index>(nodes.size());
    for (std::size_t h = 0; h < hexes.size(); ++h)
        for (Index v : hexes[h])
            if (v < 0 || v >= n)
                throw Error(what + ": hex " + std::to_string(h) + " refers to node " + std::to_string(v) +
                            " but the mesh has " + std::to_string(n) + " nodes");
    for (std::size_t i = 0; i < nodes.size(); ++i)
        for (double c : nodes[i])
            if (!std::isfinite(c))
                throw Error(what + ": node " + std::to_string(i) + " has a non-finite coordinate");
}

std::size_t HexMesh::memoryBytes() const {
    return nodes.capacity() * sizeof(Vec3) + nodeClass.capacity() * sizeof(NodeClass) +
           hexes.capacity() * sizeof(Hex) + material.capacity() * sizeof(std::int32_t);
}

}  // namespace isohex

#pragma once
// The hexahedral mesh: the one object that travels through every stage.
//
// Layout is a handful of contiguous arrays (structure of arrays) so that tens of
// millions of hexes fit: 32 bytes of connectivity + 4 bytes of material per hex,
// 24 bytes of coordinates + 8 bytes of classification per node. Topology
// (faces, edges, adjacency, sheets) is derived from nodes + hexes on demand
// (Topology.hpp) and never stored here, so there is a single source of truth.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace isohex {

using Index = std::int32_t;          // node / hex / quad / edge index
inline constexpr Index kNone = -1;   // "no such entity" (e.g. the missing hex of a boundary quad)

using Vec3 = std::array<double, 3>;

// Eight node indices in VTK_HEXAHEDRON order: 0-3 one face, 4-7 the opposite
// face with 4 above 0, numbered so that a unit cube has positive Jacobians.
using Hex = std::array<Index, 8>;

enum class NodeKind : std::uint8_t {
    Interior = 0,  // free to move anywhere
    Surface = 1,   // on a surface; NodeClass::id names the surface
    Curve = 2,     // on a curve where surfaces meet; NodeClass::id names the curve
    Fixed = 3,     // must not move (geometric vertex, user constraint)
};

const char* toString(NodeKind kind);

struct NodeClass {
    NodeKind kind = NodeKind::Interior;
    std::int32_t id = -1;  // surface or curve id for Surface / Curve, else -1
    bool operator==(const NodeClass&) const = default;
};

// A named surface the mesh must capture: the boundary of material `inside`
// against `outside` (-1 = the exterior of the mesh). Node classes and writers'
// side sets refer to surfaces by their position in HexMesh::surfaces.
struct SurfaceTag {
    std::int32_t inside = 1;
    std::int32_t outside = -1;
    std::string name;
    bool operator==(const SurfaceTag&) const = default;
};

struct HexMesh {
    std::vector<Vec3> nodes;             // world coordinates (LPS millimetres for scans)
    std::vector<NodeClass> nodeClass;    // one per node
    std::vector<Hex> hexes;
    std::vector<std::int32_t> material;  // one per hex; 1 for a single solid, 0 may be meshed exterior
    std::vector<SurfaceTag> surfaces;    // surfaces referred to by NodeClass::id
    // Curves referred to by NodeClass::id of Curve nodes, where known (meshes
    // extracted from label maps): the three materials meeting along the curve,
    // in increasing order, -1 for the exterior. Curve nodes with id -1 (where
    // four or more materials meet, or read from a file) have no entry.
    std::vector<std::array<std::int32_t, 3>> curves;

    std::size_t nodeCount() const { return nodes.size(); }
    std::size_t hexCount() const { return hexes.size(); }

    Index addNode(const Vec3& p, NodeClass c = {}) {
        nodes.push_back(p);
        nodeClass.push_back(c);
        return static_cast<Index>(nodes.size() - 1);
    }
    Index addHex(const Hex& h, std::int32_t mat = 1) {
        hexes.push_back(h);
        material.push_back(mat);
        return static_cast<Index>(hexes.size() - 1);
    }

    // Throws isohex::Error when the arrays disagree in size, an index is out of
    // range, or a coordinate is not finite. Cheap (one pass); writers call it.
    void checkConsistent(const std::string& what) const;

    // Bytes held by the arrays (capacity), for memory reports.
    std::size_t memoryBytes() const;
};

// The name used for a surface in files when SurfaceTag::name is empty:
// "boundary_m<inside>" against the exterior, "interface_m<inside>_m<outside>".
std::string surfaceName(const SurfaceTag& tag);

}  // namespace isohex

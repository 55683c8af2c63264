#pragma once
// The hexes of a closed 27-tree (RefinementTree.hpp): the leaves' hexes,
// template hexes where corners are marked, as one conformal HexMesh.
//
// Nodes are keyed by their place on the lattice of twelfths of the level-0
// nodes: a level-0 node (the centre of a grid cell, grid coordinate
// n - 1/2) has key 12n per axis; template nodes fall on twelfths of a child
// cell (TransitionTemplates.hpp), and a child of a level-l cell is 3^(l-1)
// level-0 hexes wide, so every key is an integer. Equal places get equal keys whatever cell made
// them, so sorting the keys once numbers the nodes of a conformal mesh
// (linear in the hexes, deterministic).
#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/RefinementTree.hpp"
#include "isohex/octree/TransitionTemplates.hpp"

namespace isohex::octree {

// 12x the node coordinate per axis (kKeySteps), 21 bits each (x lowest), so keys sort in
// z, y, x order like the grid's cells.
using NodeKey = std::uint64_t;
inline constexpr std::int64_t kKeySteps = kChildSteps;  // key steps per level-0 hex
inline NodeKey nodeKey(std::int64_t qx, std::int64_t qy, std::int64_t qz) {
    return static_cast<NodeKey>(qx) | static_cast<NodeKey>(qy) << 21 | static_cast<NodeKey>(qz) << 42;
}
inline std::array<std::int64_t, 3> keyCoords(NodeKey k) {
    constexpr NodeKey m = (NodeKey{1} << 21) - 1;
    return {static_cast<std::int64_t>(k & m), static_cast<std::int64_t>(k >> 21 & m), static_cast<std::int64_t>(k >> 42 & m)};
}

// How a leaf is cut into hexes: whole (one hex, as every level-0 leaf) or by
// the transition template of its marked corners (TemplateKind order).
enum class LeafForm : std::uint8_t { Whole, Vertex, Edge, Face, TwoFace, Full };
inline constexpr int kLeafForms = 6;
LeafForm leafForm(const TemplateChoice& choice);

// Per level, per LeafForm: a count of hexes or of leaves.
using FormCounts = std::vector<std::array<std::size_t, kLeafForms>>;

// The leaves' hexes before nodes are numbered: one hex per labelled grid
// point inside refined level-1 cells, one per labelled unrefined leaf without
// marked corners, a template's hexes per leaf with marked corners. Each hex's
// material is the label of the grid point whose level-0 hex holds its
// centroid (a level-0 hex: its own point), and hexes labelled 0 are left out,
// so a coarse leaf may straddle a surface and refined regions are the
// uniform mesh's hexes.
struct LeafHexes {
    std::vector<std::array<NodeKey, 8>> hexes;  // VTK order, positive on a right-handed grid
    std::vector<std::int32_t> material;
    std::vector<std::uint8_t> level;            // level of the leaf each hex fills
    std::vector<LeafForm> form;                 // how that leaf is cut
    FormCounts leavesPerForm;                   // leaves with at least one labelled hex
};
LeafHexes leafHexes(const RefinementTree& tree, const Labels& labels);

// A conformal mesh with a level per hex.
struct AdaptiveMesh {
    HexMesh mesh;
    std::vector<std::uint8_t> hexLevel;  // per hex
    std::vector<NodeKey> nodeKeys;       // per node, ascending
    std::vector<std::size_t> hexesPerLevel;
    FormCounts hexesPerForm;   // hexes per level and LeafForm
    FormCounts leavesPerForm;  // leaves per level and LeafForm (LeafHexes::leavesPerForm)
};

// Position and class of the node with a key.
using NodePlacer = std::function<void(NodeKey key, Vec3& position, NodeClass& cls)>;

// Numbers the nodes of `leaves` (ascending keys) and places each by `place`
// (default: its lattice position on the grid, interior). On a mirrored grid
// each hex's corners are reordered so it stays positively oriented.
AdaptiveMesh assembleAdaptive(const LeafHexes& leaves, const Grid& grid, const NodePlacer& place = {});

// The node of the uniform mesh (dualContourHexes of `labels`, one hex per
// labelled point, without meshExterior) at each level-0 node key.
struct UniformNodes {
    std::array<int, 3> dims{0, 0, 0};  // level-0 nodes per axis (grid points + 1)
    std::vector<Index> node;           // per level-0 node, kNone where no labelled point touches it
    UniformNodes(const Labels& labels, const HexMesh& uniform);
    // kNone for keys that are not level-0 nodes of a labelled point.
    Index at(NodeKey key) const;
};

// The adaptive mesh of a tree built over `labels`, taking every node that is
// a node of `uniform` (dualContourHexes of the same labels, one hex per
// labelled point, without meshExterior) from it with its position and class,
// and putting the others at their lattice position as interior nodes. The
// surfaces and curves are those of `uniform`.
AdaptiveMesh coarsenDualMesh(const Labels& labels, const RefinementTree& tree, const HexMesh& uniform);

}  // namespace isohex::octree

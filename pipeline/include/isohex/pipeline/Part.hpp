#pragma once
// One scan meshed in parts (docs/SPLIT-SCANS.md): the whole element grid is
// cut across its longest axis into N slabs of whole grid layers; part K
// meshes its slab plus ghost layers on each cut side, keeps the hexes of its
// own grid points, and freezes the nodes it shares with its neighbours'
// hexes before optimising, so both sides of a cut write those nodes at the
// same place. Every node carries a key (its dual-contouring cell in the whole
// grid and the sheet it was copied into) by which `isohex merge` joins the
// parts exactly (Merge.hpp).
#include <compare>
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/MeshIO.hpp"
#include "isohex/core/Pillow.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/pipeline/MeshSettings.hpp"

namespace isohex::pipeline {

// Grid layers a part samples, repairs, contours and pillows beyond each of
// its cuts. What happens at a cut node depends on the labels within a few
// layers (the repair's 2x2x2 blocks, the held-back test's neighbour hexes,
// the sheet's averaged normals) and, where the sheet's start inverts hexes,
// on the pillow's step rounds, whose halvings spread a few hexes a round for
// up to PillowOptions::maxHalvings rounds: with 8 layers two parts of ch2bet
// (1 mm, 4 parts) placed 8 sheet copies on a cut differently, by up to
// 1.2e-3 mm; with 12 they agree.
inline constexpr int kPartGhostLayers = 12;
// The thinnest slab a part may own (a node on a cut then belongs to two parts only).
inline constexpr int kPartMinLayers = 4;

// A part's place in the whole grid.
struct PartWindow {
    PartSpec spec;
    octree::Grid whole;          // the grid of the whole scan
    int axis = 0;                // the cut axis: the one with the most grid points
    int coreLo = 0, coreHi = 0;  // the part owns the hexes of grid points coreLo <= p[axis] < coreHi
    int first = 0;               // the window's first grid layer (whole-grid index along axis)
    octree::Grid grid;           // the window: layers first .. first + grid.dims[axis] - 1 of the whole grid

    bool cutBelow() const { return spec.index > 1; }
    bool cutAbove() const { return spec.index < spec.count; }
};

// The cut axis of `whole`: the one with the most grid points (the first of equals).
int partAxis(const octree::Grid& whole);

// The window of part spec.index of `whole`. With `layerWeights` (one per grid
// layer along partAxis: how much of the object each layer holds, e.g. its
// selected voxels), the cuts balance the weight: cut k is the first layer
// whose preceding layers hold k/N of it, so the parts hold about equal
// numbers of hexes (and peak memory) however the object fills the box;
// without, slabs of n * k / N layers. Every slab keeps kPartMinLayers. Throws
// SettingError when the grid has fewer than N * kPartMinLayers layers.
PartWindow partWindow(const octree::Grid& whole, PartSpec spec, const std::vector<std::int64_t>& layerWeights = {});

// Where a node comes from, the same in every part: the whole-grid cell (its
// lowest corner's whole-grid point index) of the dual-contouring vertex it
// is or was copied from, and the sheet: 0 for the vertex, 1 + material for
// its copy in that material's boundary sheet.
struct NodeKey {
    std::int64_t cell = 0;
    std::int32_t sheet = 0;
    auto operator<=>(const NodeKey&) const = default;
};

// A part's nodes as the merge needs them.
struct PartNodes {
    std::vector<NodeKey> keys;          // per node
    std::vector<std::uint8_t> onCut;    // per node: also a node of a hex another part owns
    std::vector<NodeClass> cutClasses;  // per node with onCut, in node order: its class before freezing
};

// What the report says of a part (its "part" key).
struct PartFacts {
    PartWindow window;
    std::size_t cutNodes = 0;  // nodes shared with hexes of the neighbouring parts
};

// Keys of a freshly contoured mesh, whose every vertex lies inside its cell.
std::vector<NodeKey> contourKeys(const HexMesh& mesh, const PartWindow& w);

// Appends the keys of the sheets' inner copies (pillowAllMaterials' results
// for the sorted `materials`, one pass each).
void addCopyKeys(std::vector<NodeKey>& keys, const std::vector<PillowResult>& passes,
                 const std::vector<std::int32_t>& materials);

// Keeps the hexes the part owns (a hex belongs to the slab of the largest
// whole-grid cell layer among its nodes' keys: a contoured hex to its grid
// point's, a sheet hex to the layer of its quad), drops the nodes no kept hex
// uses (order kept), and makes the nodes shared with dropped hexes Fixed.
PartNodes keepOwnHexes(HexMesh& mesh, std::vector<NodeKey> keys, const PartWindow& w);

// The materials of the hexes, ascending (the order pillowAllMaterials takes them in).
std::vector<std::int32_t> sortedMaterials(const HexMesh& mesh);

// Refuses the settings whose work is global to the whole scan and cannot be
// done slab by slab (throws SettingError naming them).
void checkPartSettings(const MeshSettings& settings);

// Gives the frozen cut nodes back their classes (for the file and the report).
void unfreezeCutNodes(HexMesh& mesh, const PartNodes& nodes);

// The part file's arrays: per node isohex_cell, isohex_sheet, isohex_on_cut;
// field data isohex_part = {index, count, axis, coreLo, coreHi, whole dims x y z,
// smallest grid step} and
// isohex_curves (the mesh's curves, three materials each).
void addPartArrays(io::WriteOptions& w, const HexMesh& mesh, const PartNodes& nodes, const PartWindow& win);

}  // namespace isohex::pipeline

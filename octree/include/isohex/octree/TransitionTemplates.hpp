#pragma once
// The 27-tree's transition templates: how an unrefined cell whose corners
// are marked (a refined neighbour touches them) is split into hexes so that
// every face shows exactly the pattern its four corners ask for, and
// neighbours conform without hanging nodes (primal 3-refinement: Schneiders
// 1996; Ito, Shih and Soni 2009).
//
// A cell is the cube [0,3]^3 in units of its children; template nodes lie on
// the lattice of twelfths of a child, so coordinates are integers 0..36 here
// (the two-face template's inner nodes need steps finer than a quarter).
// Corner c of the cell is bit c of a marked mask, c = x + 2y + 4z with x, y,
// z in {0, 1} (0 at the low side, 1 at coordinate 3).
//
// Rules the templates keep (checked in tests/octree/test_transition_templates.cpp):
// an edge is split in three iff one of its ends is marked; a face with no
// marked corner is one quad, with one the VERTEX pattern (5 quads), with the
// two of one edge the EDGE pattern (10 quads: two rows of three unit quads
// along the edge, then the 3-to-1 strip), with two diagonal, three or four
// nine unit quads (every edge of such a face is split).
//
// Masks with a template: none (plain), one corner (VERTEX), one edge (EDGE),
// one face (FACE), two adjacent faces (TWO-FACE: the convex edge of a coarse
// region wrapped by refined cells), and every mask that marks an end of each of the 12 edges
// (FULL: 27 unit cubes, every face split in nine; e.g. seven corners, the
// cell in a concave corner of a refined region, or two opposite corners of
// every face). Any other mask is promoted: corners are added, the fewest
// that reach a mask with a template, and the neighbours sharing them see the
// new marks (marked-node closure). Without FULL for masks short of eight,
// concave corners of a refined region would be refined and make new concave
// corners, which fills the bounding box of a curved boundary band.
#include <array>
#include <cstdint>
#include <span>

namespace isohex::octree {

enum class TemplateKind : std::uint8_t {
    Vertex,  // one corner marked: 7 hexes
    Edge,    // the two corners of one edge: 17 hexes
    Face,    // the four corners of one face: 31 hexes (18 unit cubes and Schneiders' 13-hex 9-to-1 layer)
    TwoFace, // the six corners of two adjacent faces: 45 hexes (24 unit cubes and a pillowed corner column)
    Full,    // every edge has a marked end: 27 unit cubes (also a refined cell's children)
};

// Lattice steps per child cell and per cell side.
inline constexpr int kChildSteps = 12;
inline constexpr int kCellSteps = 3 * kChildSteps;

// A template hex: its 8 corners in VTK order, lattice coordinates 0..36.
using TemplatePoint = std::array<std::int8_t, 3>;
using TemplateHex = std::array<TemplatePoint, 8>;

// One of the cube's 48 symmetries: y[i] = flip[i] ? 36 - x[axis[i]] : x[axis[i]].
struct CubeSymmetry {
    std::array<std::int8_t, 3> axis{0, 1, 2};
    std::array<bool, 3> flip{false, false, false};

    TemplatePoint apply(const TemplatePoint& x) const;
    // The image of a marked-corner mask.
    std::uint8_t applyToMask(std::uint8_t mask) const;
    // Whether the symmetry reverses orientation (a hex's corners are then reordered).
    bool reversesOrientation() const;
    // The template hex moved by this symmetry, corners reordered so it stays positively oriented.
    TemplateHex apply(const TemplateHex& h) const;
};

// All 48 symmetries, the identity first.
std::span<const CubeSymmetry> cubeSymmetries();

// The hexes of a template in its canonical placement: VERTEX marks corner 0,
// EDGE corners 0 and 1 (the x edge at y = z = 0), FACE corners 0-3 (z = 0),
// TWO-FACE corners 0-5 (faces y = 0 and z = 0; the x edge at y = z = 3 stays
// unsplit), FULL all eight.
std::span<const TemplateHex> templateHexes(TemplateKind kind);
// The canonical marked mask of a template kind (0x01, 0x03, 0x0F, 0x3F, 0xFF).
std::uint8_t canonicalMask(TemplateKind kind);

// What a cell with the given marked corners becomes.
struct TemplateChoice {
    enum class Action : std::uint8_t { Plain, Template, Promote } action = Action::Plain;
    TemplateKind kind = TemplateKind::Full;
    CubeSymmetry symmetry;       // maps the canonical placement onto this mask (identity for FULL)
    std::uint8_t promoteTo = 0;  // Promote: the mask to mark (a superset with a template)
};
TemplateChoice chooseTemplate(std::uint8_t markedCorners);

}  // namespace isohex::octree

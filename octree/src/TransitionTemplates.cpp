#include "isohex/octree/TransitionTemplates.hpp"

#include <algorithm>
#include <bit>
#include <vector>

namespace isohex::octree {

namespace {

// The templates as data, coordinates in twelfths of a child cell (36 = the
// cell's side, 3 children). Minimum scaled Jacobian of the raw hexes: VERTEX 1/sqrt(3) = 0.577,
// EDGE 0.408, FACE 0.302, TWO-FACE 0.258 (tests/octree/test_transition_templates.cpp).
//
// VERTEX (corner 0 marked): the corner cube [0,1]^3, then the shells
// [0,2]^3 \ [0,1]^3 and [0,3]^3 \ [0,2]^3, each as three frusta (a point of a
// shell belongs to the frustum of its largest coordinate).
//
// EDGE (x edge at y = z = 0): the 2-D vertex pattern of the yz plane swept
// along x; its unit square and inner L-shell in three slices (9 hexes), its
// outer L-shell (two pieces, y-facing and z-facing) as the 2-D 3-to-1 strip of
// the (x, radial) plane swept along the piece (4 hexes each): faces y = 0 and
// z = 0 show the EDGE pattern, x = 0 and x = 3 the VERTEX pattern.
//
// FACE (z = 0 marked): 18 hexes in z in [0, 2] (the unit cubes, but see the
// moved nodes below), then Schneiders'
// 13-hex 9-to-1 layer in z in [2, 3] (4 corner pillars, 4 edge pillars, a
// centre hex, two y-side caps, a plate and the top hex); its four sides show
// the 3-to-1 strip with the middle nodes at z = 2.5. Nodes inside the cell
// (not on its faces) are placed for quality, not on the unit lattice: the
// four middle nodes of the z = 2 layer at z = 1.5, the centre hex's top at
// (0.75..2.25, 0.75..2.25, 2.25); at their lattice places (z = 2, and
// (1..2, 1..2, 2.25)) the minimum scaled Jacobian was 0.217.
const TemplateHex kVertex[] = {
    {{{0, 0, 0}, {12, 0, 0}, {12, 12, 0}, {0, 12, 0}, {0, 0, 12}, {12, 0, 12}, {12, 12, 12}, {0, 12, 12}}},
    {{{12, 0, 0}, {24, 0, 0}, {24, 24, 0}, {12, 12, 0}, {12, 0, 12}, {24, 0, 24}, {24, 24, 24}, {12, 12, 12}}},
    {{{0, 12, 0}, {12, 12, 0}, {24, 24, 0}, {0, 24, 0}, {0, 12, 12}, {12, 12, 12}, {24, 24, 24}, {0, 24, 24}}},
    {{{0, 0, 12}, {12, 0, 12}, {12, 12, 12}, {0, 12, 12}, {0, 0, 24}, {24, 0, 24}, {24, 24, 24}, {0, 24, 24}}},
    {{{24, 0, 0}, {36, 0, 0}, {36, 36, 0}, {24, 24, 0}, {24, 0, 24}, {36, 0, 36}, {36, 36, 36}, {24, 24, 24}}},
    {{{0, 24, 0}, {24, 24, 0}, {36, 36, 0}, {0, 36, 0}, {0, 24, 24}, {24, 24, 24}, {36, 36, 36}, {0, 36, 36}}},
    {{{0, 0, 24}, {24, 0, 24}, {24, 24, 24}, {0, 24, 24}, {0, 0, 36}, {36, 0, 36}, {36, 36, 36}, {0, 36, 36}}},
};
const TemplateHex kEdge[] = {
    {{{0, 0, 0}, {12, 0, 0}, {12, 12, 0}, {0, 12, 0}, {0, 0, 12}, {12, 0, 12}, {12, 12, 12}, {0, 12, 12}}},
    {{{0, 12, 0}, {12, 12, 0}, {12, 24, 0}, {0, 24, 0}, {0, 12, 12}, {12, 12, 12}, {12, 24, 24}, {0, 24, 24}}},
    {{{0, 0, 12}, {12, 0, 12}, {12, 12, 12}, {0, 12, 12}, {0, 0, 24}, {12, 0, 24}, {12, 24, 24}, {0, 24, 24}}},
    {{{12, 0, 0}, {24, 0, 0}, {24, 12, 0}, {12, 12, 0}, {12, 0, 12}, {24, 0, 12}, {24, 12, 12}, {12, 12, 12}}},
    {{{12, 12, 0}, {24, 12, 0}, {24, 24, 0}, {12, 24, 0}, {12, 12, 12}, {24, 12, 12}, {24, 24, 24}, {12, 24, 24}}},
    {{{12, 0, 12}, {24, 0, 12}, {24, 12, 12}, {12, 12, 12}, {12, 0, 24}, {24, 0, 24}, {24, 24, 24}, {12, 24, 24}}},
    {{{24, 0, 0}, {36, 0, 0}, {36, 12, 0}, {24, 12, 0}, {24, 0, 12}, {36, 0, 12}, {36, 12, 12}, {24, 12, 12}}},
    {{{24, 12, 0}, {36, 12, 0}, {36, 24, 0}, {24, 24, 0}, {24, 12, 12}, {36, 12, 12}, {36, 24, 24}, {24, 24, 24}}},
    {{{24, 0, 12}, {36, 0, 12}, {36, 12, 12}, {24, 12, 12}, {24, 0, 24}, {36, 0, 24}, {36, 24, 24}, {24, 24, 24}}},
    {{{0, 24, 0}, {12, 24, 0}, {12, 30, 0}, {0, 36, 0}, {0, 24, 24}, {12, 24, 24}, {12, 30, 30}, {0, 36, 36}}},
    {{{0, 0, 24}, {0, 0, 36}, {12, 0, 30}, {12, 0, 24}, {0, 24, 24}, {0, 36, 36}, {12, 30, 30}, {12, 24, 24}}},
    {{{12, 24, 0}, {24, 24, 0}, {24, 30, 0}, {12, 30, 0}, {12, 24, 24}, {24, 24, 24}, {24, 30, 30}, {12, 30, 30}}},
    {{{12, 0, 24}, {12, 0, 30}, {24, 0, 30}, {24, 0, 24}, {12, 24, 24}, {12, 30, 30}, {24, 30, 30}, {24, 24, 24}}},
    {{{24, 24, 0}, {36, 24, 0}, {36, 36, 0}, {24, 30, 0}, {24, 24, 24}, {36, 24, 24}, {36, 36, 36}, {24, 30, 30}}},
    {{{24, 0, 24}, {24, 0, 30}, {36, 0, 36}, {36, 0, 24}, {24, 24, 24}, {24, 30, 30}, {36, 36, 36}, {36, 24, 24}}},
    {{{12, 30, 0}, {24, 30, 0}, {36, 36, 0}, {0, 36, 0}, {12, 30, 30}, {24, 30, 30}, {36, 36, 36}, {0, 36, 36}}},
    {{{12, 0, 30}, {0, 0, 36}, {36, 0, 36}, {24, 0, 30}, {12, 30, 30}, {0, 36, 36}, {36, 36, 36}, {24, 30, 30}}},
};
const TemplateHex kFace[] = {
    {{{0, 0, 0}, {12, 0, 0}, {12, 12, 0}, {0, 12, 0}, {0, 0, 12}, {12, 0, 12}, {12, 12, 12}, {0, 12, 12}}},
    {{{12, 0, 0}, {24, 0, 0}, {24, 12, 0}, {12, 12, 0}, {12, 0, 12}, {24, 0, 12}, {24, 12, 12}, {12, 12, 12}}},
    {{{24, 0, 0}, {36, 0, 0}, {36, 12, 0}, {24, 12, 0}, {24, 0, 12}, {36, 0, 12}, {36, 12, 12}, {24, 12, 12}}},
    {{{0, 12, 0}, {12, 12, 0}, {12, 24, 0}, {0, 24, 0}, {0, 12, 12}, {12, 12, 12}, {12, 24, 12}, {0, 24, 12}}},
    {{{12, 12, 0}, {24, 12, 0}, {24, 24, 0}, {12, 24, 0}, {12, 12, 12}, {24, 12, 12}, {24, 24, 12}, {12, 24, 12}}},
    {{{24, 12, 0}, {36, 12, 0}, {36, 24, 0}, {24, 24, 0}, {24, 12, 12}, {36, 12, 12}, {36, 24, 12}, {24, 24, 12}}},
    {{{0, 24, 0}, {12, 24, 0}, {12, 36, 0}, {0, 36, 0}, {0, 24, 12}, {12, 24, 12}, {12, 36, 12}, {0, 36, 12}}},
    {{{12, 24, 0}, {24, 24, 0}, {24, 36, 0}, {12, 36, 0}, {12, 24, 12}, {24, 24, 12}, {24, 36, 12}, {12, 36, 12}}},
    {{{24, 24, 0}, {36, 24, 0}, {36, 36, 0}, {24, 36, 0}, {24, 24, 12}, {36, 24, 12}, {36, 36, 12}, {24, 36, 12}}},
    {{{0, 0, 12}, {12, 0, 12}, {12, 12, 12}, {0, 12, 12}, {0, 0, 24}, {12, 0, 24}, {12, 12, 18}, {0, 12, 24}}},
    {{{12, 0, 12}, {24, 0, 12}, {24, 12, 12}, {12, 12, 12}, {12, 0, 24}, {24, 0, 24}, {24, 12, 18}, {12, 12, 18}}},
    {{{24, 0, 12}, {36, 0, 12}, {36, 12, 12}, {24, 12, 12}, {24, 0, 24}, {36, 0, 24}, {36, 12, 24}, {24, 12, 18}}},
    {{{0, 12, 12}, {12, 12, 12}, {12, 24, 12}, {0, 24, 12}, {0, 12, 24}, {12, 12, 18}, {12, 24, 18}, {0, 24, 24}}},
    {{{12, 12, 12}, {24, 12, 12}, {24, 24, 12}, {12, 24, 12}, {12, 12, 18}, {24, 12, 18}, {24, 24, 18}, {12, 24, 18}}},
    {{{24, 12, 12}, {36, 12, 12}, {36, 24, 12}, {24, 24, 12}, {24, 12, 18}, {36, 12, 24}, {36, 24, 24}, {24, 24, 18}}},
    {{{0, 24, 12}, {12, 24, 12}, {12, 36, 12}, {0, 36, 12}, {0, 24, 24}, {12, 24, 18}, {12, 36, 24}, {0, 36, 24}}},
    {{{12, 24, 12}, {24, 24, 12}, {24, 36, 12}, {12, 36, 12}, {12, 24, 18}, {24, 24, 18}, {24, 36, 24}, {12, 36, 24}}},
    {{{24, 24, 12}, {36, 24, 12}, {36, 36, 12}, {24, 36, 12}, {24, 24, 18}, {36, 24, 24}, {36, 36, 24}, {24, 36, 24}}},
    {{{0, 0, 24}, {12, 0, 24}, {12, 12, 18}, {0, 12, 24}, {0, 0, 36}, {12, 0, 30}, {9, 9, 27}, {0, 12, 30}}},
    {{{24, 0, 24}, {36, 0, 24}, {36, 12, 24}, {24, 12, 18}, {24, 0, 30}, {36, 0, 36}, {36, 12, 30}, {27, 9, 27}}},
    {{{0, 24, 24}, {12, 24, 18}, {12, 36, 24}, {0, 36, 24}, {0, 24, 30}, {9, 27, 27}, {12, 36, 30}, {0, 36, 36}}},
    {{{24, 24, 18}, {36, 24, 24}, {36, 36, 24}, {24, 36, 24}, {27, 27, 27}, {36, 24, 30}, {36, 36, 36}, {24, 36, 30}}},
    {{{12, 0, 24}, {24, 0, 24}, {24, 12, 18}, {12, 12, 18}, {12, 0, 30}, {24, 0, 30}, {27, 9, 27}, {9, 9, 27}}},
    {{{0, 12, 24}, {12, 12, 18}, {12, 24, 18}, {0, 24, 24}, {0, 12, 30}, {9, 9, 27}, {9, 27, 27}, {0, 24, 30}}},
    {{{24, 12, 18}, {36, 12, 24}, {36, 24, 24}, {24, 24, 18}, {27, 9, 27}, {36, 12, 30}, {36, 24, 30}, {27, 27, 27}}},
    {{{12, 24, 18}, {24, 24, 18}, {24, 36, 24}, {12, 36, 24}, {9, 27, 27}, {27, 27, 27}, {24, 36, 30}, {12, 36, 30}}},
    {{{12, 12, 18}, {24, 12, 18}, {24, 24, 18}, {12, 24, 18}, {9, 9, 27}, {27, 9, 27}, {27, 27, 27}, {9, 27, 27}}},
    {{{12, 0, 30}, {24, 0, 30}, {27, 9, 27}, {9, 9, 27}, {0, 0, 36}, {36, 0, 36}, {36, 12, 30}, {0, 12, 30}}},
    {{{9, 27, 27}, {27, 27, 27}, {24, 36, 30}, {12, 36, 30}, {0, 24, 30}, {36, 24, 30}, {36, 36, 36}, {0, 36, 36}}},
    {{{9, 9, 27}, {27, 9, 27}, {27, 27, 27}, {9, 27, 27}, {0, 12, 30}, {36, 12, 30}, {36, 24, 30}, {0, 24, 30}}},
    {{{0, 12, 30}, {36, 12, 30}, {36, 24, 30}, {0, 24, 30}, {0, 0, 36}, {36, 0, 36}, {36, 36, 36}, {0, 36, 36}}},
};

// TWO-FACE (faces y = 0 and z = 0 marked; the x edge C at y = z = 3 unsplit):
// faces y = 0, z = 0, x = 0, x = 3 split in nine, y = 3 and z = 3 the EDGE
// pattern, whose 3-to-1 strips meet at C. The eight columns (y, z) outside
// [2,3]^2 are unit cubes (the last 24 rows); the corner column [0,3] x [2,3]^2
// is a pillowed core: one hex on each of its 16 boundary quads (rows 6-21),
// around five core hexes (rows 1-5) with the same boundary combinatorics: a
// long central hex from x = 0 to 3 and, on each of its four long sides, one
// hex taking that side's quads (the inner faces' three, the strips' four).
// The pillow is needed: the strips' top quads share C, so the hexes behind
// them differ, and the five quads at a corner of C need five hexes around an
// inner edge. Built and checked by tools/two-face-template.py (inner nodes on
// twelfths of a child: raw minimum scaled Jacobian 0.258, 1/sqrt(15)).
const TemplateHex kTwoFace[] = {
    {{{12, 34, 25}, {12, 33, 28}, {6, 30, 30}, {6, 29, 28}, {24, 34, 25}, {22, 33, 28}, {29, 29, 29}, {29, 30, 27}}},
    {{{13, 25, 25}, {12, 34, 25}, {6, 29, 28}, {6, 28, 28}, {22, 25, 25}, {24, 34, 25}, {29, 30, 27}, {28, 27, 27}}},
    {{{6, 28, 28}, {6, 29, 28}, {6, 30, 30}, {7, 28, 30}, {28, 27, 27}, {29, 30, 27}, {29, 29, 29}, {29, 27, 30}}},
    {{{13, 25, 35}, {13, 25, 25}, {6, 28, 28}, {7, 28, 30}, {24, 25, 34}, {22, 25, 25}, {28, 27, 27}, {29, 27, 30}}},
    {{{7, 28, 30}, {6, 30, 30}, {12, 29, 34}, {13, 25, 35}, {29, 27, 30}, {29, 29, 29}, {24, 28, 33}, {24, 25, 34}}},
    {{{7, 28, 30}, {6, 30, 30}, {6, 29, 28}, {6, 28, 28}, {0, 24, 36}, {0, 36, 36}, {0, 36, 24}, {0, 24, 24}}},
    {{{28, 27, 27}, {29, 30, 27}, {29, 29, 29}, {29, 27, 30}, {36, 24, 24}, {36, 36, 24}, {36, 36, 36}, {36, 24, 36}}},
    {{{6, 28, 28}, {6, 29, 28}, {12, 34, 25}, {13, 25, 25}, {0, 24, 24}, {0, 36, 24}, {12, 36, 24}, {12, 24, 24}}},
    {{{13, 25, 25}, {12, 34, 25}, {24, 34, 25}, {22, 25, 25}, {12, 24, 24}, {12, 36, 24}, {24, 36, 24}, {24, 24, 24}}},
    {{{22, 25, 25}, {24, 34, 25}, {29, 30, 27}, {28, 27, 27}, {24, 24, 24}, {24, 36, 24}, {36, 36, 24}, {36, 24, 24}}},
    {{{13, 25, 25}, {13, 25, 35}, {7, 28, 30}, {6, 28, 28}, {12, 24, 24}, {12, 24, 36}, {0, 24, 36}, {0, 24, 24}}},
    {{{22, 25, 25}, {24, 25, 34}, {13, 25, 35}, {13, 25, 25}, {24, 24, 24}, {24, 24, 36}, {12, 24, 36}, {12, 24, 24}}},
    {{{28, 27, 27}, {29, 27, 30}, {24, 25, 34}, {22, 25, 25}, {36, 24, 24}, {36, 24, 36}, {24, 24, 36}, {24, 24, 24}}},
    {{{6, 30, 30}, {12, 33, 28}, {12, 34, 25}, {6, 29, 28}, {0, 36, 36}, {12, 36, 30}, {12, 36, 24}, {0, 36, 24}}},
    {{{12, 33, 28}, {22, 33, 28}, {24, 34, 25}, {12, 34, 25}, {12, 36, 30}, {24, 36, 30}, {24, 36, 24}, {12, 36, 24}}},
    {{{22, 33, 28}, {29, 29, 29}, {29, 30, 27}, {24, 34, 25}, {24, 36, 30}, {36, 36, 36}, {36, 36, 24}, {24, 36, 24}}},
    {{{6, 30, 30}, {29, 29, 29}, {22, 33, 28}, {12, 33, 28}, {0, 36, 36}, {36, 36, 36}, {24, 36, 30}, {12, 36, 30}}},
    {{{7, 28, 30}, {13, 25, 35}, {12, 29, 34}, {6, 30, 30}, {0, 24, 36}, {12, 24, 36}, {12, 30, 36}, {0, 36, 36}}},
    {{{13, 25, 35}, {24, 25, 34}, {24, 28, 33}, {12, 29, 34}, {12, 24, 36}, {24, 24, 36}, {24, 30, 36}, {12, 30, 36}}},
    {{{24, 25, 34}, {29, 27, 30}, {29, 29, 29}, {24, 28, 33}, {24, 24, 36}, {36, 24, 36}, {36, 36, 36}, {24, 30, 36}}},
    {{{12, 29, 34}, {24, 28, 33}, {29, 29, 29}, {6, 30, 30}, {12, 30, 36}, {24, 30, 36}, {36, 36, 36}, {0, 36, 36}}},
    {{{0, 0, 0}, {12, 0, 0}, {12, 12, 0}, {0, 12, 0}, {0, 0, 12}, {12, 0, 12}, {12, 12, 12}, {0, 12, 12}}},
    {{{12, 0, 0}, {24, 0, 0}, {24, 12, 0}, {12, 12, 0}, {12, 0, 12}, {24, 0, 12}, {24, 12, 12}, {12, 12, 12}}},
    {{{24, 0, 0}, {36, 0, 0}, {36, 12, 0}, {24, 12, 0}, {24, 0, 12}, {36, 0, 12}, {36, 12, 12}, {24, 12, 12}}},
    {{{0, 12, 0}, {12, 12, 0}, {12, 24, 0}, {0, 24, 0}, {0, 12, 12}, {12, 12, 12}, {12, 24, 12}, {0, 24, 12}}},
    {{{12, 12, 0}, {24, 12, 0}, {24, 24, 0}, {12, 24, 0}, {12, 12, 12}, {24, 12, 12}, {24, 24, 12}, {12, 24, 12}}},
    {{{24, 12, 0}, {36, 12, 0}, {36, 24, 0}, {24, 24, 0}, {24, 12, 12}, {36, 12, 12}, {36, 24, 12}, {24, 24, 12}}},
    {{{0, 24, 0}, {12, 24, 0}, {12, 36, 0}, {0, 36, 0}, {0, 24, 12}, {12, 24, 12}, {12, 36, 12}, {0, 36, 12}}},
    {{{12, 24, 0}, {24, 24, 0}, {24, 36, 0}, {12, 36, 0}, {12, 24, 12}, {24, 24, 12}, {24, 36, 12}, {12, 36, 12}}},
    {{{24, 24, 0}, {36, 24, 0}, {36, 36, 0}, {24, 36, 0}, {24, 24, 12}, {36, 24, 12}, {36, 36, 12}, {24, 36, 12}}},
    {{{0, 0, 12}, {12, 0, 12}, {12, 12, 12}, {0, 12, 12}, {0, 0, 24}, {12, 0, 24}, {12, 12, 24}, {0, 12, 24}}},
    {{{12, 0, 12}, {24, 0, 12}, {24, 12, 12}, {12, 12, 12}, {12, 0, 24}, {24, 0, 24}, {24, 12, 24}, {12, 12, 24}}},
    {{{24, 0, 12}, {36, 0, 12}, {36, 12, 12}, {24, 12, 12}, {24, 0, 24}, {36, 0, 24}, {36, 12, 24}, {24, 12, 24}}},
    {{{0, 12, 12}, {12, 12, 12}, {12, 24, 12}, {0, 24, 12}, {0, 12, 24}, {12, 12, 24}, {12, 24, 24}, {0, 24, 24}}},
    {{{12, 12, 12}, {24, 12, 12}, {24, 24, 12}, {12, 24, 12}, {12, 12, 24}, {24, 12, 24}, {24, 24, 24}, {12, 24, 24}}},
    {{{24, 12, 12}, {36, 12, 12}, {36, 24, 12}, {24, 24, 12}, {24, 12, 24}, {36, 12, 24}, {36, 24, 24}, {24, 24, 24}}},
    {{{0, 24, 12}, {12, 24, 12}, {12, 36, 12}, {0, 36, 12}, {0, 24, 24}, {12, 24, 24}, {12, 36, 24}, {0, 36, 24}}},
    {{{12, 24, 12}, {24, 24, 12}, {24, 36, 12}, {12, 36, 12}, {12, 24, 24}, {24, 24, 24}, {24, 36, 24}, {12, 36, 24}}},
    {{{24, 24, 12}, {36, 24, 12}, {36, 36, 12}, {24, 36, 12}, {24, 24, 24}, {36, 24, 24}, {36, 36, 24}, {24, 36, 24}}},
    {{{0, 0, 24}, {12, 0, 24}, {12, 12, 24}, {0, 12, 24}, {0, 0, 36}, {12, 0, 36}, {12, 12, 36}, {0, 12, 36}}},
    {{{12, 0, 24}, {24, 0, 24}, {24, 12, 24}, {12, 12, 24}, {12, 0, 36}, {24, 0, 36}, {24, 12, 36}, {12, 12, 36}}},
    {{{24, 0, 24}, {36, 0, 24}, {36, 12, 24}, {24, 12, 24}, {24, 0, 36}, {36, 0, 36}, {36, 12, 36}, {24, 12, 36}}},
    {{{0, 12, 24}, {12, 12, 24}, {12, 24, 24}, {0, 24, 24}, {0, 12, 36}, {12, 12, 36}, {12, 24, 36}, {0, 24, 36}}},
    {{{12, 12, 24}, {24, 12, 24}, {24, 24, 24}, {12, 24, 24}, {12, 12, 36}, {24, 12, 36}, {24, 24, 36}, {12, 24, 36}}},
    {{{24, 12, 24}, {36, 12, 24}, {36, 24, 24}, {24, 24, 24}, {24, 12, 36}, {36, 12, 36}, {36, 24, 36}, {24, 24, 36}}},
};

std::vector<TemplateHex> unitCubes(int layers) {
    std::vector<TemplateHex> out;
    static constexpr int ref[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                      {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    for (int k = 0; k < layers; ++k)
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i) {
                TemplateHex h;
                for (int c = 0; c < 8; ++c)
                    h[c] = {static_cast<std::int8_t>(kChildSteps * (i + ref[c][0])),
                            static_cast<std::int8_t>(kChildSteps * (j + ref[c][1])),
                            static_cast<std::int8_t>(kChildSteps * (k + ref[c][2]))};
                out.push_back(h);
            }
    return out;
}

std::vector<CubeSymmetry> makeSymmetries() {
    std::vector<CubeSymmetry> out;
    std::array<std::int8_t, 3> axis{0, 1, 2};
    do {
        for (int f = 0; f < 8; ++f) {
            CubeSymmetry s;
            s.axis = axis;
            s.flip = {(f & 1) != 0, (f & 2) != 0, (f & 4) != 0};
            out.push_back(s);
        }
    } while (std::next_permutation(axis.begin(), axis.end()));
    return out;
}

// Whether every one of the cube's 12 edges has a marked end (then every face
// is split in nine and the 27 unit cubes conform).
bool coversEveryEdge(int mask) {
    for (int c = 0; c < 8; ++c)
        for (int axis = 0; axis < 3; ++axis) {
            const int d = c | 1 << axis;
            if (d != c && !(mask >> c & 1) && !(mask >> d & 1)) return false;
        }
    return true;
}

struct ChoiceTable {
    std::array<TemplateChoice, 256> choice;

    static TemplateChoice direct(int m) {
        TemplateChoice c;
        if (m == 0) return c;
        for (TemplateKind k : {TemplateKind::Vertex, TemplateKind::Edge, TemplateKind::Face, TemplateKind::TwoFace})
            for (const CubeSymmetry& s : cubeSymmetries())
                if (s.applyToMask(canonicalMask(k)) == m) return {TemplateChoice::Action::Template, k, s, 0};
        if (coversEveryEdge(m)) return {TemplateChoice::Action::Template, TemplateKind::Full, CubeSymmetry{}, 0};
        c.action = TemplateChoice::Action::Promote;
        return c;
    }

    ChoiceTable() {
        for (int m = 0; m < 256; ++m) choice[static_cast<std::size_t>(m)] = direct(m);
        // Promotion: the superset with a template and the fewest added corners;
        // among those a transition template before FULL, then the smallest mask.
        for (int m = 0; m < 256; ++m) {
            TemplateChoice& c = choice[static_cast<std::size_t>(m)];
            if (c.action != TemplateChoice::Action::Promote) continue;
            int best = 0xFF;
            const auto rank = [&](int s) {
                const bool full = choice[static_cast<std::size_t>(s)].kind == TemplateKind::Full;
                return std::popcount(static_cast<unsigned>(s)) * 1024 + full * 512 + s;
            };
            for (int s = 0; s < 256; ++s)
                if ((s & m) == m && choice[static_cast<std::size_t>(s)].action == TemplateChoice::Action::Template &&
                    rank(s) < rank(best))
                    best = s;
            c.promoteTo = static_cast<std::uint8_t>(best);
        }
    }
};

}  // namespace

TemplatePoint CubeSymmetry::apply(const TemplatePoint& x) const {
    TemplatePoint y;
    for (int i = 0; i < 3; ++i) {
        const std::int8_t v = x[static_cast<std::size_t>(axis[static_cast<std::size_t>(i)])];
        y[static_cast<std::size_t>(i)] =
            flip[static_cast<std::size_t>(i)] ? static_cast<std::int8_t>(kCellSteps - v) : v;
    }
    return y;
}

std::uint8_t CubeSymmetry::applyToMask(std::uint8_t mask) const {
    std::uint8_t out = 0;
    for (int c = 0; c < 8; ++c) {
        if (!(mask >> c & 1)) continue;
        const TemplatePoint p = apply(TemplatePoint{static_cast<std::int8_t>(kCellSteps * (c & 1)),
                                                    static_cast<std::int8_t>(kCellSteps * (c >> 1 & 1)),
                                                    static_cast<std::int8_t>(kCellSteps * (c >> 2 & 1))});
        out = static_cast<std::uint8_t>(out |
                                        1u << (p[0] / kCellSteps + 2 * (p[1] / kCellSteps) + 4 * (p[2] / kCellSteps)));
    }
    return out;
}

bool CubeSymmetry::reversesOrientation() const {
    // parity of the axis permutation times one sign per flipped axis
    int inversions = (axis[0] > axis[1]) + (axis[0] > axis[2]) + (axis[1] > axis[2]);
    inversions += flip[0] + flip[1] + flip[2];
    return (inversions & 1) != 0;
}

TemplateHex CubeSymmetry::apply(const TemplateHex& h) const {
    static constexpr int keep[8] = {0, 1, 2, 3, 4, 5, 6, 7};
    static constexpr int mirror[8] = {0, 3, 2, 1, 4, 7, 6, 5};
    const int* order = reversesOrientation() ? mirror : keep;
    TemplateHex out;
    for (int c = 0; c < 8; ++c) out[static_cast<std::size_t>(c)] = apply(h[static_cast<std::size_t>(order[c])]);
    return out;
}

std::span<const CubeSymmetry> cubeSymmetries() {
    static const std::vector<CubeSymmetry> all = makeSymmetries();
    return all;
}

std::span<const TemplateHex> templateHexes(TemplateKind kind) {
    static const std::vector<TemplateHex> full = unitCubes(3);
    switch (kind) {
    case TemplateKind::Vertex: return kVertex;
    case TemplateKind::Edge: return kEdge;
    case TemplateKind::Face: return kFace;
    case TemplateKind::TwoFace: return kTwoFace;
    case TemplateKind::Full: break;
    }
    return full;
}

std::uint8_t canonicalMask(TemplateKind kind) {
    switch (kind) {
    case TemplateKind::Vertex: return 0x01;
    case TemplateKind::Edge: return 0x03;
    case TemplateKind::Face: return 0x0F;
    case TemplateKind::TwoFace: return 0x3F;
    case TemplateKind::Full: break;
    }
    return 0xFF;
}

TemplateChoice chooseTemplate(std::uint8_t markedCorners) {
    static const ChoiceTable table;
    return table.choice[markedCorners];
}

}  // namespace isohex::octree

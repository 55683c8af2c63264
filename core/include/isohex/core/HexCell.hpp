#pragma once
// Local tables of the VTK_HEXAHEDRON reference cell, shared by topology,
// quality, validity, writers and sheet operations.
#include <array>

namespace isohex::hexcell {

// Faces with node order giving the outward normal by the right-hand rule.
// Faces 2k and 2k+1 are opposite (the three chords through a hex).
inline constexpr std::array<std::array<int, 4>, 6> kFaces = {{
    {0, 4, 7, 3},  // 0: xi = 0
    {1, 2, 6, 5},  // 1: xi = 1
    {0, 1, 5, 4},  // 2: eta = 0
    {3, 7, 6, 2},  // 3: eta = 1
    {0, 3, 2, 1},  // 4: zeta = 0
    {4, 5, 6, 7},  // 5: zeta = 1
}};

// Edges; edges 4k..4k+3 are parallel (xi, eta, zeta direction): the four
// edges of a hex that belong to one sheet.
inline constexpr std::array<std::array<int, 2>, 12> kEdges = {{
    {0, 1}, {3, 2}, {4, 5}, {7, 6},  // xi
    {0, 3}, {1, 2}, {4, 7}, {5, 6},  // eta
    {0, 4}, {1, 5}, {2, 6}, {3, 7},  // zeta
}};

// Corner k: its three neighbours along xi, eta, zeta (right-handed for a
// positive hex), as Verdict and Mesquite use them.
inline constexpr std::array<std::array<int, 3>, 8> kCornerNeighbours = {{
    {1, 3, 4}, {2, 0, 5}, {3, 1, 6}, {0, 2, 7},
    {7, 5, 0}, {4, 6, 1}, {5, 7, 2}, {6, 4, 3},
}};

// Exodus II side numbers (1-based) for our local faces.
inline constexpr std::array<int, 6> kExodusSide = {4, 2, 1, 3, 5, 6};

}  // namespace isohex::hexcell

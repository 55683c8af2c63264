#pragma once
// Small meshes for the mesh-file tests (tests/core/test_io.cpp and the
// make_test_meshes helper the Python round-trip test drives).
#include <array>
#include <cmath>

#include "isohex/core/HexMesh.hpp"

namespace isohex::iotest {

// The 24 proper rotations of the reference cube, as corner permutations of a
// VTK-ordered hex: rotation r sends corner k to corner kRotations[r][k]. Used
// to renumber hexes without changing their shape or orientation, so every
// local face lands on every side of a block.
inline std::array<std::array<int, 8>, 24> cubeRotations() {
    // Corner k of the VTK hex as a point of {-1,1}^3.
    const int corner[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                              {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
    std::array<std::array<int, 8>, 24> out{};
    int count = 0;
    const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    const int permSign[6] = {1, -1, -1, 1, 1, -1};
    for (int p = 0; p < 6; ++p)
        for (int s = 0; s < 8; ++s) {
            const int sg[3] = {s & 1 ? -1 : 1, s & 2 ? -1 : 1, s & 4 ? -1 : 1};
            if (permSign[p] * sg[0] * sg[1] * sg[2] != 1) continue;  // keep det = +1
            for (int k = 0; k < 8; ++k) {
                int q[3];
                for (int a = 0; a < 3; ++a) q[a] = sg[a] * corner[k][perms[p][a]];
                for (int j = 0; j < 8; ++j)
                    if (corner[j][0] == q[0] && corner[j][1] == q[1] && corner[j][2] == q[2]) out[count][k] = j;
            }
            ++count;
        }
    return out;
}

// nx*ny*nz hexes of edge h from the origin. Hexes with x-centre below half
// the width get material `matLow`, the others `matHigh`. With `rotate`, hex i
// is renumbered by rotation (7 i mod 24). Nodes get varied classifications
// (so a format that keeps them can be checked) and the mesh names its
// surfaces the default way.
inline HexMesh makeTwoMaterialBlock(int nx, int ny, int nz, double h, std::int32_t matLow = 1,
                                    std::int32_t matHigh = 2, bool rotate = true) {
    HexMesh m;
    auto id = [&](int i, int j, int k) { return static_cast<Index>((k * (ny + 1) + j) * (nx + 1) + i); };
    for (int k = 0; k <= nz; ++k)
        for (int j = 0; j <= ny; ++j)
            for (int i = 0; i <= nx; ++i) {
                NodeClass c;
                const int n = static_cast<int>(m.nodes.size());
                c.kind = static_cast<NodeKind>(n % 4);
                c.id = c.kind == NodeKind::Surface || c.kind == NodeKind::Curve ? n % 3 : -1;
                m.addNode({i * h, j * h, k * h}, c);
            }
    const auto rot = cubeRotations();
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const Hex base = {id(i, j, k),         id(i + 1, j, k),         id(i + 1, j + 1, k),
                                  id(i, j + 1, k),     id(i, j, k + 1),         id(i + 1, j, k + 1),
                                  id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)};
                Hex hex = base;
                if (rotate) {
                    const auto& r = rot[(7 * m.hexes.size()) % 24];
                    for (int c = 0; c < 8; ++c) hex[c] = base[r[c]];
                }
                m.addHex(hex, 2 * i + 1 < nx ? matLow : matHigh);
            }
    m.surfaces = {{matLow, -1, ""}, {matHigh, -1, "outer_skin_of_material_two"}, {matLow, matHigh, ""}};
    return m;
}

}  // namespace isohex::iotest

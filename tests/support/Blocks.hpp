#pragma once
// Small structured meshes for tests.
#include "isohex/core/HexMesh.hpp"

namespace isohex::test {

// nx x ny x nz unit-spaced hexes (times `h`) starting at `origin`, VTK order,
// positive Jacobians, all of material `mat`.
inline HexMesh makeBlock(int nx, int ny, int nz, double h = 1.0, Vec3 origin = {0, 0, 0}, int mat = 1) {
    HexMesh m;
    auto id = [&](int i, int j, int k) { return static_cast<Index>((k * (ny + 1) + j) * (nx + 1) + i); };
    for (int k = 0; k <= nz; ++k)
        for (int j = 0; j <= ny; ++j)
            for (int i = 0; i <= nx; ++i) m.addNode({origin[0] + i * h, origin[1] + j * h, origin[2] + k * h});
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                m.addHex({id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k), id(i, j, k + 1),
                          id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)},
                         mat);
    return m;
}

}  // namespace isohex::test

#pragma once
// Small label grids and checks shared by the octree tests.
#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Validate.hpp"

namespace isohex::test {

// Dual contouring alone may leave inverted boundary hexes (the reason the
// fundamental sheet is pillowed in afterwards); what it must deliver is a
// topologically valid mesh: every defect kind but inversion is an error here.
inline bool topologicallyValid(const HexMesh& m) {
    ValidityReport v = validate(m);
    v.defects.erase("inverted_hex");
    if (!v.ok()) ADD_FAILURE() << toJson(v).dump();
    return v.ok();
}

inline std::vector<std::int32_t> grid3(int n) { return std::vector<std::int32_t>(static_cast<std::size_t>(n) * n * n, 0); }
inline void set(std::vector<std::int32_t>& v, int n, int i, int j, int k, std::int32_t m = 1) {
    v[(static_cast<std::size_t>(k) * n + j) * n + i] = m;
}
// An n^3 grid with material 1 at the points lo..hi on every axis.
inline std::vector<std::int32_t> solidBlock(int n, int lo, int hi) {
    auto v = grid3(n);
    for (int k = lo; k <= hi; ++k)
        for (int j = lo; j <= hi; ++j)
            for (int i = lo; i <= hi; ++i) set(v, n, i, j, k);
    return v;
}

}  // namespace isohex::test

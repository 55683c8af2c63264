// The digital topology of one grid point: Euler change and topological numbers.
#include "DigitalTopology.hpp"

#include <algorithm>
#include <cstdlib>

namespace isohex::octree {

int eulerChange(const Labels& l, int i, int j, int k, std::int32_t m, bool add) {
    const auto [nx, ny, nz] = l.grid.dims;
    bool in[3][3][3];
    for (int a = -1; a <= 1; ++a)
        for (int b = -1; b <= 1; ++b)
            for (int c = -1; c <= 1; ++c) {
                const int x = i + a, y = j + b, z = k + c;
                const bool inside = x >= 0 && y >= 0 && z >= 0 && x < nx && y < ny && z < nz;
                in[a + 1][b + 1][c + 1] = (a || b || c) && inside && l.material[l.grid.index(x, y, z)] == m;
            }
    int chi = 0;
    // The cells of the point's cube are indexed by offsets s != 0 in {-1,0,1}^3:
    // a face (one non-zero axis), an edge (two) or a vertex (three). A cell is
    // in K when an m-neighbour at offset t shares it: t != 0 with t_a in
    // {0, s_a} on every axis.
    for (int a = -1; a <= 1; ++a)
        for (int b = -1; b <= 1; ++b)
            for (int c = -1; c <= 1; ++c) {
                const int nonzero = (a != 0) + (b != 0) + (c != 0);
                if (nonzero == 0) continue;
                bool inK = false;
                for (int ta = std::min(a, 0); ta <= std::max(a, 0) && !inK; ++ta)
                    for (int tb = std::min(b, 0); tb <= std::max(b, 0) && !inK; ++tb)
                        for (int tc = std::min(c, 0); tc <= std::max(c, 0) && !inK; ++tc)
                            inK = in[ta + 1][tb + 1][tc + 1];
                if (inK) chi += nonzero == 1 ? 1 : nonzero == 2 ? -1 : 1;
            }
    return add ? 1 - chi : chi - 1;
}

int topoNumber(const std::array<bool, 27>& in, int adjacency) {
    auto axes = [](int q) { return (q % 3 != 1) + (q / 3 % 3 != 1) + (q / 9 != 1); };
    std::array<bool, 27> use{};
    for (int q = 0; q < 27; ++q) use[q] = q != 13 && in[q] && (adjacency == 26 || axes(q) <= 2);
    std::array<bool, 27> seen{};
    int count = 0;
    for (int s = 0; s < 27; ++s) {
        if (!use[s] || seen[s]) continue;
        int stack[27], top = 0;
        stack[top++] = s;
        seen[s] = true;
        bool counts = adjacency == 26;
        while (top) {
            const int p = stack[--top];
            counts = counts || axes(p) == 1;
            for (int q = 0; q < 27; ++q) {
                if (!use[q] || seen[q]) continue;
                const int da = std::abs(p % 3 - q % 3), db = std::abs(p / 3 % 3 - q / 3 % 3), dc = std::abs(p / 9 - q / 9);
                if (da > 1 || db > 1 || dc > 1) continue;
                if (adjacency == 6 && da + db + dc != 1) continue;
                seen[q] = true;
                stack[top++] = q;
            }
        }
        count += counts;
    }
    return count;
}

}  // namespace isohex::octree

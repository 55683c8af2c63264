// The 2x2x2 blocks of grid points: manifold tests (see GridBlocks.hpp).
#include "GridBlocks.hpp"

#include <algorithm>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Parallel.hpp"
#include "isohex/octree/Labels.hpp"

namespace isohex::octree {

const ManifoldTable kTable;

int badPairs(const std::array<std::int32_t, 8>& mat) {
    std::array<std::int32_t, 8> distinct{};
    int nd = 0;
    for (int c = 0; c < 8; ++c) {
        bool seen = false;
        for (int e = 0; e < nd; ++e) seen = seen || distinct[e] == mat[c];
        if (!seen) distinct[nd++] = mat[c];
    }
    if (nd < 3) return 0;
    // block edges: corner c to c | (1 << d) where bit d of c is clear
    static constexpr auto edges = [] {
        std::array<std::array<int, 2>, 12> e{};
        int n = 0;
        for (int c = 0; c < 8; ++c)
            for (int d = 0; d < 3; ++d)
                if (!(c >> d & 1)) e[n++] = {c, c | (1 << d)};
        return e;
    }();
    // block squares: the 6 faces, each listing its 4 edges by index
    static constexpr auto squares = [] {
        std::array<std::array<int, 4>, 6> sq{};
        int n = 0;
        for (int d = 0; d < 3; ++d)
            for (int side = 0; side < 2; ++side) {
                int k = 0;
                for (int e = 0; e < 12; ++e)
                    if (((edges[e][0] >> d & 1) == side) && ((edges[e][1] >> d & 1) == side)) sq[n][k++] = e;
                ++n;
            }
        return sq;
    }();
    int bad = 0;
    for (int x = 0; x < nd; ++x)
        for (int y = x + 1; y < nd; ++y) {
            const std::int32_t a = distinct[x], b = distinct[y];
            unsigned faces = 0;
            for (int e = 0; e < 12; ++e) {
                const std::int32_t p = mat[edges[e][0]], q = mat[edges[e][1]];
                if ((p == a && q == b) || (p == b && q == a)) faces |= 1u << e;
            }
            if (faces == 0) continue;
            FixedDisjointSets<int, 12> sets;
            for (const auto& sq : squares) {
                int in[4], n = 0;
                for (int e : sq)
                    if (faces >> e & 1) in[n++] = e;
                if (n == 2) sets.unite(in[0], in[1]);
            }
            int components = 0;
            for (int e = 0; e < 12; ++e)
                if ((faces >> e & 1) && sets.isRoot(e)) ++components;
            bad += components > 1;
        }
    return bad;
}

std::vector<std::size_t> badBlocks(const Labels& l) {
    const auto [nx, ny, nz] = l.grid.dims;
    if (nx < 2 || ny < 2 || nz < 2) return {};
    return parallel::collectSorted<std::size_t>(
        static_cast<std::size_t>(nz - 1), 1, [&](const auto& r, std::vector<std::size_t>& out) {
            for (int k = static_cast<int>(r.begin()); k != static_cast<int>(r.end()); ++k)
                for (int j = 0; j < ny - 1; ++j) {
                    // rows of the two z-layers of the blocks, x fastest
                    const std::int32_t* row[4] = {
                        &l.material[l.grid.index(0, j, k)], &l.material[l.grid.index(0, j + 1, k)],
                        &l.material[l.grid.index(0, j, k + 1)], &l.material[l.grid.index(0, j + 1, k + 1)]};
                    for (int i = 0; i < nx - 1; ++i) {
                        const std::int32_t m0 = row[0][i];
                        if (row[0][i + 1] == m0 && row[1][i] == m0 && row[1][i + 1] == m0 && row[2][i] == m0 &&
                            row[2][i + 1] == m0 && row[3][i] == m0 && row[3][i + 1] == m0)
                            continue;  // uniform: manifold
                        const BlockView b = block(l, i, j, k);
                        if (!blockManifold(b.mat)) out.push_back(l.grid.index(i, j, k));
                    }
                }
        });
}

std::vector<std::size_t> badBlocksAmong(const Labels& l, std::vector<std::size_t> candidates) {
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    const auto [nx, ny, nz] = l.grid.dims;
    std::vector<std::size_t> out;
    for (std::size_t b : candidates) {
        const int i = static_cast<int>(b % nx), j = static_cast<int>(b / nx % ny), k = static_cast<int>(b / nx / ny);
        if (i >= nx - 1 || j >= ny - 1 || k >= nz - 1) continue;
        const BlockView v = block(l, i, j, k);
        if (!uniformBlock(v.mat) && !blockManifold(v.mat)) out.push_back(b);
    }
    return out;
}

}  // namespace isohex::octree

#include "isohex/octree/SurfaceCoarsening.hpp"

#include <algorithm>

#include <tbb/parallel_for.h>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::octree {

namespace {

// The labels of one cell's block (its points and one point around them), x fastest.
struct Block {
    int n = 0;  // points per axis
    std::vector<std::int32_t> label;
    std::vector<std::uint8_t> in;  // scratch: membership of the set being tested

    std::size_t index(int i, int j, int k) const {
        return (static_cast<std::size_t>(k) * static_cast<std::size_t>(n) + static_cast<std::size_t>(j)) *
                   static_cast<std::size_t>(n) +
               static_cast<std::size_t>(i);
    }
    bool onBorder(int i, int j, int k) const {
        return i == 0 || j == 0 || k == 0 || i == n - 1 || j == n - 1 || k == n - 1;
    }
    void load(const Labels& labels, int side, int ci, int cj, int ck) {
        n = side + 2;
        label.resize(static_cast<std::size_t>(n) * n * n);
        in.resize(label.size());
        std::size_t p = 0;
        for (int k = 0; k < n; ++k)
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i) label[p++] = labels.at(side * ci - 1 + i, side * cj - 1 + j, side * ck - 1 + k);
    }
};

// Components of `in` under 6-adjacency, over all its points (border: only
// the points on the block's border, joined along the border).
int components(const Block& b, bool border, DisjointSets<std::int32_t>& sets) {
    sets.reset(b.in.size());
    const int n = b.n;
    int count = 0;
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const std::size_t p = b.index(i, j, k);
                if (!b.in[p] || (border && !b.onBorder(i, j, k))) continue;
                ++count;
                const int q[3][3] = {{i - 1, j, k}, {i, j - 1, k}, {i, j, k - 1}};
                for (const auto& r : q) {
                    if (r[0] < 0 || r[1] < 0 || r[2] < 0) continue;
                    const std::size_t s = b.index(r[0], r[1], r[2]);
                    if (!b.in[s] || (border && !b.onBorder(r[0], r[1], r[2]))) continue;
                    if (sets.find(static_cast<std::int32_t>(p)) != sets.find(static_cast<std::int32_t>(s))) {
                        sets.unite(static_cast<std::int32_t>(p), static_cast<std::int32_t>(s));
                        --count;
                    }
                }
            }
    return count;
}

// Euler characteristic of `in` as a cubical complex under 6-adjacency:
// points - unit edges + unit squares - unit cubes with every corner in the set.
long euler6(const Block& b) {
    const int n = b.n;
    long chi = 0;
    const auto at = [&](int i, int j, int k) { return i < n && j < n && k < n && b.in[b.index(i, j, k)]; };
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                if (!at(i, j, k)) continue;
                const bool x = at(i + 1, j, k), y = at(i, j + 1, k), z = at(i, j, k + 1);
                const bool xy = x && y && at(i + 1, j + 1, k), yz = y && z && at(i, j + 1, k + 1),
                           xz = x && z && at(i + 1, j, k + 1);
                const bool xyz = xy && yz && xz && at(i + 1, j + 1, k + 1);
                chi += 1 - (x + y + z) + (xy + yz + xz) - xyz;
            }
    return chi;
}

// Whether the points labelled `m` in the block are one disk-like part: one
// component, Euler characteristic 1, one patch on the block's border.
bool simplePart(Block& b, std::int32_t m, DisjointSets<std::int32_t>& sets) {
    for (std::size_t p = 0; p < b.label.size(); ++p) b.in[p] = b.label[p] == m;
    return components(b, false, sets) == 1 && components(b, true, sets) == 1 && euler6(b) == 1;
}

// Whether a cell with this block must be refined.
bool mustRefine(Block& b, DisjointSets<std::int32_t>& sets) {
    const std::int32_t a = b.label[0];
    std::int32_t other = a;
    for (std::int32_t m : b.label) {
        if (m == a || m == other) continue;
        if (other != a) return true;  // three labels
        other = m;
    }
    if (other == a) return false;
    return !simplePart(b, a, sets) || !simplePart(b, other, sets);
}

}  // namespace

RequestMasks surfaceRequests(const Labels& labels, int top) {
    RequestMasks req(static_cast<std::size_t>(top) + 1);
    const auto points = labels.grid.dims;
    int side = 1;
    for (int l = 1; l <= top; ++l) {
        side *= 3;
        const auto cells = levelDims(points, l);
        const auto childCells = levelDims(points, l - 1);
        auto& want = req[static_cast<std::size_t>(l)];
        want.assign(static_cast<std::size_t>(cells[0]) * cells[1] * cells[2], 0);
        const std::vector<std::uint8_t>* below = l >= 2 ? &req[static_cast<std::size_t>(l) - 1] : nullptr;
        const auto childRequested = [&](int ci, int cj, int ck) {
            for (int z = 0; z < 3; ++z)
                for (int y = 0; y < 3; ++y)
                    for (int x = 0; x < 3; ++x) {
                        const int i = 3 * ci + x, j = 3 * cj + y, k = 3 * ck + z;
                        if (i >= childCells[0] || j >= childCells[1] || k >= childCells[2]) continue;
                        if ((*below)[(static_cast<std::size_t>(k) * childCells[1] + j) * childCells[0] + i]) return true;
                    }
            return false;
        };
        tbb::parallel_for(0, cells[2], [&](int ck) {
            Block b;
            DisjointSets<std::int32_t> sets;
            for (int cj = 0; cj < cells[1]; ++cj)
                for (int ci = 0; ci < cells[0]; ++ci) {
                    if (below && childRequested(ci, cj, ck)) continue;  // the closure refines it
                    b.load(labels, side, ci, cj, ck);
                    want[(static_cast<std::size_t>(ck) * cells[1] + cj) * cells[0] + ci] = mustRefine(b, sets) ? 1 : 0;
                }
        });
    }
    return req;
}

}  // namespace isohex::octree

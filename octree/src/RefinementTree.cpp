#include "isohex/octree/RefinementTree.hpp"

#include <algorithm>

#include <tbb/parallel_for.h>

#include "isohex/core/Error.hpp"
#include "isohex/octree/TransitionTemplates.hpp"

namespace isohex::octree {

namespace {

// The marked corners of cell (i, j, k): corner (dx, dy, dz) is marked when one
// of the 8 cells around it is refined.
std::uint8_t markedCorners(const RefinementLevel& L, int i, int j, int k) {
    bool r[3][3][3];
    for (int c = 0; c < 3; ++c)
        for (int b = 0; b < 3; ++b)
            for (int a = 0; a < 3; ++a) {
                const int x = i + a - 1, y = j + b - 1, z = k + c - 1;
                r[c][b][a] = L.contains(x, y, z) && L.refined[L.index(x, y, z)] != 0;
            }
    std::uint8_t mask = 0;
    for (int corner = 0; corner < 8; ++corner) {
        const int dx = corner & 1, dy = corner >> 1 & 1, dz = corner >> 2 & 1;
        bool marked = false;
        for (int n = 0; n < 8 && !marked; ++n) marked = r[dz + (n >> 2 & 1)][dy + (n >> 1 & 1)][dx + (n & 1)];
        if (marked) mask = static_cast<std::uint8_t>(mask | 1u << corner);
    }
    return mask;
}

// Promotion to a fixed point: an unrefined cell whose marked corners no
// template takes is refined, which marks more corners. Sweeps in index order
// update in place (a promotion is seen by the cells after it in the same
// sweep), so the result depends on the refined set alone. Returns how many
// cells were promoted.
std::size_t closeLevel(RefinementLevel& L) {
    std::size_t promoted = 0;
    for (bool changed = true; changed;) {
        changed = false;
        for (int k = 0; k < L.dims[2]; ++k)
            for (int j = 0; j < L.dims[1]; ++j)
                for (int i = 0; i < L.dims[0]; ++i) {
                    const std::size_t c = L.index(i, j, k);
                    if (L.refined[c]) continue;
                    if (chooseTemplate(markedCorners(L, i, j, k)).action != TemplateChoice::Action::Refine) continue;
                    L.refined[c] = 1;
                    ++promoted;
                    changed = true;
                }
    }
    for (int k = 0; k < L.dims[2]; ++k)
        for (int j = 0; j < L.dims[1]; ++j)
            for (int i = 0; i < L.dims[0]; ++i) {
                const std::size_t c = L.index(i, j, k);
                L.marks[c] = L.refined[c] ? 0 : markedCorners(L, i, j, k);
            }
    return promoted;
}

// Refines the parent of every level-(l-1) cell that is refined or carries a
// template. Returns how many parents that refined which were not refined yet.
std::size_t refineParents(const RefinementLevel& child, RefinementLevel& parent) {
    std::size_t added = 0;
    for (int k = 0; k < child.dims[2]; ++k)
        for (int j = 0; j < child.dims[1]; ++j)
            for (int i = 0; i < child.dims[0]; ++i) {
                const std::size_t c = child.index(i, j, k);
                if (!child.refined[c] && !child.marks[c]) continue;
                std::uint8_t& p = parent.refined[parent.index(i / 3, j / 3, k / 3)];
                added += p == 0;
                p = 1;
            }
    return added;
}

}  // namespace

RefinementTree closeRefinement(const std::array<int, 3>& points, int top,
                               const std::vector<std::vector<std::uint8_t>>& requests) {
    if (top < 1) throw Error("the refinement tree needs at least one level above the finest hexes");
    RefinementTree tree;
    tree.points = points;
    tree.levels.resize(static_cast<std::size_t>(top) + 1);
    tree.promoted.assign(static_cast<std::size_t>(top) + 1, 0);
    tree.requested.assign(static_cast<std::size_t>(top) + 1, 0);
    int step = 1;
    for (int l = 1; l <= top; ++l) {
        step *= 3;
        RefinementLevel& L = tree.levels[static_cast<std::size_t>(l)];
        for (int c = 0; c < 3; ++c) L.dims[c] = std::max(1, (points[c] + step - 1) / step);
        const std::size_t n = static_cast<std::size_t>(L.dims[0]) * L.dims[1] * L.dims[2];
        L.refined.assign(n, 0);
        L.marks.assign(n, 0);
        if (static_cast<std::size_t>(l) < requests.size() && !requests[static_cast<std::size_t>(l)].empty()) {
            const auto& want = requests[static_cast<std::size_t>(l)];
            if (want.size() != n) throw Error("refinement request of the wrong size for its level");
            for (std::size_t c = 0; c < n; ++c)
                if (want[c]) {
                    L.refined[c] = 1;
                    ++tree.requested[static_cast<std::size_t>(l)];
                }
        }
    }
    for (int l = 1; l <= top; ++l) {
        RefinementLevel& L = tree.levels[static_cast<std::size_t>(l)];
        std::size_t& promoted = tree.promoted[static_cast<std::size_t>(l)];
        if (l >= 2) promoted += refineParents(tree.levels[static_cast<std::size_t>(l) - 1], L);
        promoted += closeLevel(L);
    }
    return tree;
}

RefinementTree refineAtLabelChanges(const Labels& labels, const RefinementSettings& settings) {
    const auto dims = labels.grid.dims;
    const int widest = std::max({dims[0], dims[1], dims[2]});
    int top = 1;  // the highest level whose cells are not wider than the grid
    for (int side = 9; top < settings.maxLevel && side <= widest; side *= 3) ++top;
    std::array<int, 3> cells;
    for (int c = 0; c < 3; ++c) cells[c] = std::max(1, (dims[c] + 2) / 3);
    std::vector<std::vector<std::uint8_t>> requests(2);
    auto& want = requests[1];
    want.assign(static_cast<std::size_t>(cells[0]) * cells[1] * cells[2], 0);
    tbb::parallel_for(0, cells[2], [&](int ck) {
        for (int cj = 0; cj < cells[1]; ++cj)
            for (int ci = 0; ci < cells[0]; ++ci) {
                const std::int32_t first = labels.at(3 * ci - 1, 3 * cj - 1, 3 * ck - 1);
                bool uniform = true;
                for (int k = 3 * ck - 1; k <= 3 * ck + 3 && uniform; ++k)
                    for (int j = 3 * cj - 1; j <= 3 * cj + 3 && uniform; ++j)
                        for (int i = 3 * ci - 1; i <= 3 * ci + 3 && uniform; ++i) uniform = labels.at(i, j, k) == first;
                want[(static_cast<std::size_t>(ck) * cells[1] + cj) * cells[0] + ci] = uniform ? 0 : 1;
            }
    });
    return closeRefinement(dims, top, requests);
}

}  // namespace isohex::octree

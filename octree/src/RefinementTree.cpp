#include "isohex/octree/RefinementTree.hpp"

#include <algorithm>

#include <tbb/parallel_for.h>

#include "isohex/core/Error.hpp"
#include "isohex/octree/Grading.hpp"
#include "isohex/octree/TransitionTemplates.hpp"

namespace isohex::octree {

namespace {

// Marked corners of one level: one byte per cell corner.
struct CornerMarks {
    std::array<int, 3> dims;  // corners per axis (cells + 1)
    std::vector<std::uint8_t> marked;

    explicit CornerMarks(const RefinementLevel& L)
        : dims{L.dims[0] + 1, L.dims[1] + 1, L.dims[2] + 1},
          marked(static_cast<std::size_t>(dims[0]) * dims[1] * dims[2], 0) {}
    std::size_t index(int i, int j, int k) const {
        return (static_cast<std::size_t>(k) * static_cast<std::size_t>(dims[1]) + static_cast<std::size_t>(j)) *
                   static_cast<std::size_t>(dims[0]) +
               static_cast<std::size_t>(i);
    }
    // The mask of cell (i, j, k): bit x + 2y + 4z for its corner (i + x, j + y, k + z).
    std::uint8_t mask(int i, int j, int k) const {
        std::uint8_t m = 0;
        for (int c = 0; c < 8; ++c)
            if (marked[index(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))]) m = static_cast<std::uint8_t>(m | 1u << c);
        return m;
    }
    void mark(int i, int j, int k, std::uint8_t m) {
        for (int c = 0; c < 8; ++c)
            if (m >> c & 1) marked[index(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))] = 1;
    }
};

// Marked-node closure of one level: refined cells mark their 8 corners; an
// unrefined cell whose mask has no template marks the corners its promotion
// adds (TemplateChoice::promoteTo), until nothing changes. Sweeps in index
// order update in place, so the result depends on the refined set alone.
// Leaves each unrefined cell's mask in L.marks; returns how many cells were
// promoted.
std::size_t closeLevel(RefinementLevel& L) {
    CornerMarks corners(L);
    for (int k = 0; k < L.dims[2]; ++k)
        for (int j = 0; j < L.dims[1]; ++j)
            for (int i = 0; i < L.dims[0]; ++i)
                if (L.refined[L.index(i, j, k)]) corners.mark(i, j, k, 0xFF);
    std::size_t promoted = 0;
    for (bool changed = true; changed;) {
        changed = false;
        for (int k = 0; k < L.dims[2]; ++k)
            for (int j = 0; j < L.dims[1]; ++j)
                for (int i = 0; i < L.dims[0]; ++i) {
                    if (L.refined[L.index(i, j, k)]) continue;
                    const TemplateChoice c = chooseTemplate(corners.mask(i, j, k));
                    if (c.action != TemplateChoice::Action::Promote) continue;
                    corners.mark(i, j, k, c.promoteTo);
                    ++promoted;
                    changed = true;
                }
    }
    for (int k = 0; k < L.dims[2]; ++k)
        for (int j = 0; j < L.dims[1]; ++j)
            for (int i = 0; i < L.dims[0]; ++i) {
                const std::size_t c = L.index(i, j, k);
                L.marks[c] = L.refined[c] ? 0 : corners.mask(i, j, k);
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
                               const std::vector<std::vector<std::uint8_t>>& requests, int grading) {
    if (top < 1) throw Error("the refinement tree needs at least one level above the finest hexes");
    RefinementTree tree;
    tree.points = points;
    tree.levels.resize(static_cast<std::size_t>(top) + 1);
    tree.promoted.assign(static_cast<std::size_t>(top) + 1, 0);
    tree.requested.assign(static_cast<std::size_t>(top) + 1, 0);
    tree.graded.assign(static_cast<std::size_t>(top) + 1, 0);
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
        if (l >= 2 && grading > 0)
            tree.graded[static_cast<std::size_t>(l)] =
                refineGradedParents(tree.levels[static_cast<std::size_t>(l) - 1], L, grading);
        promoted += closeLevel(L);
    }
    return tree;
}

int topLevelFor(const std::array<int, 3>& points, int maxLevel) {
    const int widest = std::max({points[0], points[1], points[2]});
    int top = 1;  // the highest level whose cells are not wider than the grid
    for (int side = 9; top < maxLevel && side <= widest; side *= 3) ++top;
    return top;
}

std::vector<std::vector<std::uint8_t>> labelChangeRequests(const Labels& labels) {
    const auto dims = labels.grid.dims;
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
    return requests;
}

RefinementTree refineAtLabelChanges(const Labels& labels, const RefinementSettings& settings) {
    return closeRefinement(labels.grid.dims, topLevelFor(labels.grid.dims, settings.maxLevel),
                           labelChangeRequests(labels));
}

}  // namespace isohex::octree

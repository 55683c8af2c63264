// Edits of the labels: dropping specks, filling one-cell pits, moving points
// where the mesh keeps inverted hexes.
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <tuple>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "DigitalTopology.hpp"
#include "GridBlocks.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/GridEdits.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/Regions.hpp"

namespace isohex::octree {

std::size_t keepLargestComponents(Labels& labels) {
    const std::size_t n = labels.material.size();
    DisjointSets<std::uint32_t> sets = materialRegions(labels, Adjacency::Face);
    auto find = [&](std::size_t a) { return sets.find(static_cast<std::uint32_t>(a)); };
    // size of each component, then the largest root per material (ties: smallest root)
    std::vector<std::uint32_t> size(n, 0);
    for (std::size_t p = 0; p < n; ++p)
        if (labels.material[p] != 0) ++size[find(p)];
    std::map<std::int32_t, std::uint32_t> best;
    for (std::size_t p = 0; p < n; ++p) {
        const std::int32_t m = labels.material[p];
        if (m == 0 || !sets.isRoot(static_cast<std::uint32_t>(p))) continue;
        auto it = best.find(m);
        if (it == best.end() || size[p] > size[it->second]) best[m] = static_cast<std::uint32_t>(p);
    }
    std::size_t removed = 0;
    for (std::size_t p = 0; p < n; ++p) {
        const std::int32_t m = labels.material[p];
        if (m != 0 && find(p) != best[m]) {
            labels.material[p] = 0;
            ++removed;
        }
    }
    return removed;
}

std::size_t fillOneCellPits(Labels& labels) {
    const auto [nx, ny, nz] = labels.grid.dims;
    if (nx < 3 || ny < 3 || nz < 3) return 0;
    auto& mat = labels.material;
    const std::ptrdiff_t sx = static_cast<std::ptrdiff_t>(labels.grid.index(1, 0, 0) - labels.grid.index(0, 0, 0));
    const std::ptrdiff_t sy = static_cast<std::ptrdiff_t>(labels.grid.index(0, 1, 0) - labels.grid.index(0, 0, 0));
    const std::ptrdiff_t sz = static_cast<std::ptrdiff_t>(labels.grid.index(0, 0, 1) - labels.grid.index(0, 0, 0));
    const std::array<std::ptrdiff_t, 6> step{-sx, sx, -sy, sy, -sz, sz};
    auto interior = [&](std::size_t q) {
        const auto i = static_cast<int>(q % static_cast<std::size_t>(nx));
        const auto j = static_cast<int>(q / static_cast<std::size_t>(nx) % static_cast<std::size_t>(ny));
        const auto k = static_cast<int>(q / (static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny)));
        return i > 0 && j > 0 && k > 0 && i + 1 < nx && j + 1 < ny && k + 1 < nz;
    };
    // Material a pit would join (0: not a pit); `open` gets the face
    // neighbour through which it opens.
    auto pitMaterial = [&](std::size_t q, std::size_t* open) -> std::int32_t {
        if (mat[q] != 0 || !interior(q)) return 0;
        std::int32_t m = 0;
        int count = 0, background = 0;
        for (int d = 0; d < 6; ++d) {
            const std::size_t n = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(q) + step[d]);
            const std::int32_t b = mat[n];
            if (b == 0) {
                ++background;
                if (open) *open = n;
            } else if (m == 0 || b == m) {
                m = b;
                ++count;
            }
        }
        return count == 5 && background == 1 ? m : 0;
    };
    std::vector<std::size_t> candidates;
    {
        // first pass: the whole grid, slab by slab in parallel, in index order
        std::vector<std::vector<std::size_t>> perSlab(static_cast<std::size_t>(nz));
        tbb::parallel_for(tbb::blocked_range<int>(1, nz - 1), [&](const auto& r) {
            for (int k = r.begin(); k != r.end(); ++k)
                for (int j = 1; j + 1 < ny; ++j)
                    for (int i = 1; i + 1 < nx; ++i) {
                        const std::size_t q = labels.grid.index(i, j, k);
                        if (pitMaterial(q, nullptr) != 0) perSlab[static_cast<std::size_t>(k)].push_back(q);
                    }
        });
        for (auto& v : perSlab) candidates.insert(candidates.end(), v.begin(), v.end());
    }
    std::size_t filled = 0;
    std::vector<std::size_t> fill;
    std::vector<std::int32_t> to;
    while (!candidates.empty()) {
        std::sort(candidates.begin(), candidates.end());
        candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
        fill.clear();
        to.clear();
        for (std::size_t q : candidates) {
            std::size_t open = 0;
            const std::int32_t m = pitMaterial(q, &open);
            // two pits opening into each other are a closed two-point cavity
            if (m != 0 && pitMaterial(open, nullptr) == 0) {
                fill.push_back(q);
                to.push_back(m);
            }
        }
        for (std::size_t t = 0; t < fill.size(); ++t) mat[fill[t]] = to[t];
        filled += fill.size();
        // only the background neighbours of what was filled can have become pits
        candidates.clear();
        for (std::size_t q : fill)
            for (int d = 0; d < 6; ++d) {
                const std::size_t n = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(q) + step[d]);
                if (pitMaterial(n, nullptr) != 0) candidates.push_back(n);
            }
    }
    return filled;
}

namespace {

// Whether point (i, j, k) (not on the grid's outer layer) leaving material
// `from` for `to` keeps the components, tunnels and cavities of both (simple
// for each: its neighbours of that material one 26-component, the rest one
// 6-component in the 18-neighbourhood) and leaves the 8 blocks around it
// manifold. A point joining or leaving the object must also keep the
// topology of the union of all materials (and so of the background: its
// pockets, the exterior). Tried on the labels and undone.
bool editKeepsTopology(Labels& labels, int i, int j, int k, std::int32_t from, std::int32_t to) {
    const Grid& g = labels.grid;
    auto& mat = labels.material;
    std::array<std::int32_t, 27> m27;
    for (int q = 0; q < 27; ++q) m27[q] = mat[g.index(i + q % 3 - 1, j + q / 3 % 3 - 1, k + q / 9 - 1)];
    // simple for the set of points whose label passes `inSet`
    auto simple = [&](auto inSet) {
        std::array<bool, 27> in{}, out{};
        for (int q = 0; q < 27; ++q) {
            in[q] = q != 13 && inSet(m27[q]);
            out[q] = q != 13 && !inSet(m27[q]);
        }
        return topoNumber(in, 26) == 1 && topoNumber(out, 6) == 1;
    };
    auto material = [](std::int32_t m) { return [m](std::int32_t x) { return x == m; }; };
    if ((from != 0 && !simple(material(from))) || (to != 0 && !simple(material(to)))) return false;
    if ((from == 0 || to == 0) && !simple([](std::int32_t x) { return x != 0; })) return false;
    const std::size_t p = g.index(i, j, k);
    mat[p] = to;
    bool manifold = true;
    for (int c = 0; c < 8 && manifold; ++c) {
        const int bi = i - (c & 1), bj = j - (c >> 1 & 1), bk = k - (c >> 2 & 1);
        manifold = blockManifold(block(labels, bi, bj, bk).mat);
    }
    mat[p] = from;
    return manifold;
}

}  // namespace

std::vector<PointEdit> editNearInvertedHexes(Labels& labels, const std::vector<std::array<double, 3>>& positions,
                                             const std::vector<std::size_t>& frozen, int maxSame) {
    const Grid& g = labels.grid;
    const auto [nx, ny, nz] = g.dims;
    std::vector<PointEdit> edits;
    if (nx < 3 || ny < 3 || nz < 3) return edits;
    auto& mat = labels.material;
    auto isFrozen = [&](std::size_t p) { return std::find(frozen.begin(), frozen.end(), p) != frozen.end(); };
    const int faceStep[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    for (const auto& x : positions) {
        bool onGrid = true;
        for (int a = 0; a < 3; ++a) onGrid = onGrid && std::isfinite(x[a]) && x[a] > -1 && x[a] < g.dims[a];
        if (!onGrid) continue;
        const int ci = static_cast<int>(std::lround(x[0])), cj = static_cast<int>(std::lround(x[1])),
                  ck = static_cast<int>(std::lround(x[2]));
        // the most exposed point, then the material most of its neighbours
        // hold, then the nearest, then the first
        using Key = std::tuple<int, int, double, std::size_t, std::int32_t>;
        std::optional<Key> best;
        std::int32_t bestFrom = 0;
        bool nearEdit = false;
        for (int dk = -1; dk <= 1; ++dk)
            for (int dj = -1; dj <= 1; ++dj)
                for (int di = -1; di <= 1; ++di) {
                    const int i = ci + di, j = cj + dj, k = ck + dk;
                    // points on the outer layer stay background; their blocks reach past it
                    if (i < 1 || j < 1 || k < 1 || i + 1 >= nx || j + 1 >= ny || k + 1 >= nz) continue;
                    const std::size_t p = g.index(i, j, k);
                    if (std::any_of(edits.begin(), edits.end(), [&](const PointEdit& e) { return e.point == p; })) nearEdit = true;
                    if (isFrozen(p)) continue;
                    const std::int32_t from = mat[p];
                    std::array<std::int32_t, 6> nb;
                    int same = 0;
                    for (int d = 0; d < 6; ++d) {
                        nb[d] = mat[g.index(i + faceStep[d][0], j + faceStep[d][1], k + faceStep[d][2])];
                        same += nb[d] == from;
                    }
                    if (same > maxSame) continue;
                    const double dist = (x[0] - i) * (x[0] - i) + (x[1] - j) * (x[1] - j) + (x[2] - k) * (x[2] - k);
                    for (int d = 0; d < 6; ++d) {
                        const std::int32_t to = nb[d];
                        if (to == from || std::find(nb.begin(), nb.begin() + d, to) != nb.begin() + d) continue;
                        const Key key{same, -static_cast<int>(std::count(nb.begin(), nb.end(), to)), dist, p, to};
                        if ((best && !(key < *best)) || !editKeepsTopology(labels, i, j, k, from, to)) continue;
                        best = key;
                        bestFrom = from;
                    }
                }
        // one edit per place: a second inverted hex of an edited place waits
        // for the next attempt, which sees the mesh this edit gives
        if (!best || nearEdit) continue;
        const std::size_t p = std::get<3>(*best);
        mat[p] = std::get<4>(*best);
        edits.push_back({p, bestFrom, mat[p]});
    }
    return edits;
}

}  // namespace isohex::octree

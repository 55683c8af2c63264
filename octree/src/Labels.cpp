// Grid labelling, non-manifold repair and region topology.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <tuple>
#include <functional>
#include <set>
#include <unordered_map>
#include <unordered_set>
#include <sstream>
#include <random>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Error.hpp"
#include "GridBlocks.hpp"
#include "PolygonWindow.hpp"
#include "isohex/octree/DualContour.hpp"

namespace isohex::octree {

std::array<double, 3> Grid::spacing() const {
    std::array<double, 3> s;
    for (int a = 0; a < 3; ++a)
        s[a] = std::sqrt(axes[a][0] * axes[a][0] + axes[a][1] * axes[a][1] + axes[a][2] * axes[a][2]);
    return s;
}

double Grid::determinant() const {
    const auto& a = axes[0];
    const auto& b = axes[1];
    const auto& c = axes[2];
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

Labels sampleLabels(const Domain& domain, const Grid& grid, bool keepBorder) {
    Labels l;
    l.grid = grid;
    l.material.assign(grid.size(), 0);
    const auto [nx, ny, nz] = grid.dims;
    tbb::parallel_for(tbb::blocked_range<int>(0, nz), [&](const auto& r) {
        for (int k = r.begin(); k != r.end(); ++k)
            for (int j = 0; j < ny; ++j)
                for (int i = 0; i < nx; ++i) {
                    const bool border = i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1;
                    if (border && !keepBorder) continue;
                    l.material[grid.index(i, j, k)] = domain.materialAt(grid.point(i, j, k));
                }
    });
    return l;
}

namespace {

// Change of the Euler characteristic of material m's solid (the union of the
// closed cubes around its points) when point (i, j, k) joins it (`add`) or
// leaves it: the point's cube meets the cubes of its m-neighbours in a complex
// K of its faces, edges and vertices, and chi changes by +-(1 - chi(K)). The
// boundary surface's chi is twice the solid's, so 0 means the flip keeps the
// Euler characteristic that regionTopology reports.
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

// Topological number of the set `in` (3x3x3 neighbourhood, x fastest, the
// centre ignored) for 6- or 26-adjacency (Bertrand and Malandain 1994): with
// 6, the 6-components of the set within the 18-neighbourhood that hold a
// 6-neighbour of the centre; with 26, the 26-components in the 26-neighbourhood.
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

// Region ids of the repair (see repairNonManifold): union-find over ids, so a
// flip that has to join two regions merges their ids.
struct RegionIds {
    std::vector<std::int32_t> id;        // per grid point (meaningful for material points)
    DisjointSets<std::int32_t> regions;  // over the ids (root: the smallest id of the merged ones)
    std::int32_t of(std::size_t p) { return regions.find(id[p]); }
    std::int32_t fresh() { return regions.add(); }
};

// Whether point (i, j, k) may leave material `from` and join `to` without
// changing the topology of the surface volumeToMesh draws around either: a
// material's region (its points with one region id, 26-adjacent, as marching
// cubes joins points touching along an edge or at a corner unless they belong
// to regions it keeps apart) against everything else (6-adjacent, as marching
// cubes never joins pockets of the outside through an edge) keeps its
// components, tunnels and cavities: the point is simple for both (topological
// numbers 1 and 1). A point joining `to` must touch exactly one of its regions.
// 2 when the flip is simple for both materials; 1 when only what lies
// outside them keeps its topology (the model of the regions is coarser than
// marching cubes, that of the outside matches it); 0 otherwise.
int flipTier(const Labels& l, RegionIds& r, int i, int j, int k, std::int32_t from, std::int32_t to,
             const CellEdgeGroups* mc) {
    const auto [nx, ny, nz] = l.grid.dims;
    std::array<std::int32_t, 27> mat;
    std::array<std::size_t, 27> pt{};
    for (int q = 0; q < 27; ++q) {
        const int x = i + q % 3 - 1, y = j + q / 3 % 3 - 1, z = k + q / 9 - 1;
        const bool inside = x >= 0 && y >= 0 && z >= 0 && x < nx && y < ny && z < nz;
        pt[q] = inside ? l.grid.index(x, y, z) : 0;
        mat[q] = inside ? l.material[pt[q]] : 0;
    }
    bool regionKeeps = true, restKeeps = true;
    auto check = [&](std::int32_t m, std::int32_t region) {
        std::array<bool, 27> in{}, out{};
        for (int q = 0; q < 27; ++q) {
            if (q == 13) continue;
            in[q] = region >= 0 && mat[q] == m && r.of(pt[q]) == region;
            out[q] = mat[q] != m;
        }
        regionKeeps = regionKeeps && region >= 0 && topoNumber(in, 26) == 1;
        restKeeps = restKeeps && topoNumber(out, 6) == 1;
    };
    if (from != 0) check(from, r.of(pt[13]));
    if (to != 0) {
        std::int32_t region = -1;
        bool several = false;
        for (int q = 0; q < 27; ++q) {
            if (q == 13 || mat[q] != to) continue;
            const std::int32_t o = r.of(pt[q]);
            several = several || (region >= 0 && o != region);
            region = o;
        }
        check(to, several ? -1 : region);
    }
    const int model = restKeeps ? (regionKeeps ? 2 : 1) : 0;
    if (!mc) return model;
    // with the polygoniser's tables: 3 when the flip keeps both surfaces
    // exactly; 2 when it keeps the Euler characteristic of both (it may join
    // or split pieces: one tunnel for one component); else the model's tier
    long long dFrom = 0, dTo = 0;
    const bool exact = (from == 0 || mcKeeps(l, i, j, k, from, *mc, &dFrom)) &&
                       (to == 0 || mcKeeps(l, i, j, k, to, *mc, &dTo));
    if (exact) return 3;
    // (a flip that fails for `from` does not test `to`: test it for the Euler change)
    if (from != 0 && to != 0 && dTo == 0) mcKeeps(l, i, j, k, to, *mc, &dTo);
    return dFrom == 0 && dTo == 0 ? 2 : std::min(model, 1);
}

bool simpleFlip(const Labels& l, RegionIds& r, int i, int j, int k, std::int32_t from, std::int32_t to,
                const CellEdgeGroups* mc) {
    return flipTier(l, r, i, j, k, from, to, mc) == (mc ? 3 : 2);
}

// Gives point p material `to`, with the region id of its new neighbours
// (merging their regions if it touches several; a fresh region if none).
void flipPoint(Labels& l, RegionIds& r, std::size_t p, std::int32_t to) {
    l.material[p] = to;
    if (to == 0) return;
    const auto [nx, ny, nz] = l.grid.dims;
    const int i = static_cast<int>(p % nx), j = static_cast<int>(p / nx % ny), k = static_cast<int>(p / nx / ny);
    std::int32_t region = -1;
    for (int q = 0; q < 27; ++q) {
        const int x = i + q % 3 - 1, y = j + q / 3 % 3 - 1, z = k + q / 9 - 1;
        if (q == 13 || x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
        const std::size_t o = l.grid.index(x, y, z);
        if (l.material[o] != to) continue;
        const std::int32_t ro = r.of(o);
        if (region < 0) region = ro;
        else if (ro != region)
            region = r.regions.unite(ro, region);
    }
    r.id[p] = region >= 0 ? region : r.fresh();
}

}  // namespace

std::size_t countNonManifoldBlocks(const Labels& labels) { return badBlocks(labels).size(); }

std::size_t keepLargestComponents(Labels& labels) {
    const auto [nx, ny, nz] = labels.grid.dims;
    const std::size_t n = labels.material.size();
    DisjointSets<std::uint32_t> sets(n);
    auto find = [&](std::size_t a) { return sets.find(static_cast<std::uint32_t>(a)); };
    auto unite = [&](std::size_t a, std::size_t b) {
        sets.unite(static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b));
    };
    const Grid& g = labels.grid;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t p = g.index(i, j, k);
                const std::int32_t m = labels.material[p];
                if (m == 0) continue;
                if (i + 1 < nx && labels.material[g.index(i + 1, j, k)] == m) unite(p, g.index(i + 1, j, k));
                if (j + 1 < ny && labels.material[g.index(i, j + 1, k)] == m) unite(p, g.index(i, j + 1, k));
                if (k + 1 < nz && labels.material[g.index(i, j, k + 1)] == m) unite(p, g.index(i, j, k + 1));
            }
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

namespace {

// Region ids for the repair: the given ones, or each material's 26-connected
// components (points touching along an edge or at a corner in one region).
RegionIds initialRegions(const Labels& labels, const std::vector<std::int32_t>* given) {
    RegionIds r;
    const std::size_t n = labels.material.size();
    r.id.assign(n, 0);
    if (given) {
        if (given->size() != n) throw Error("repairNonManifold: one region id per grid point expected");
        std::map<std::int32_t, std::int32_t> dense;
        for (std::size_t p = 0; p < n; ++p)
            if (labels.material[p] != 0) {
                auto [it, fresh] = dense.emplace((*given)[p], static_cast<std::int32_t>(dense.size()));
                r.id[p] = it->second;
            }
        r.regions.reset(dense.size());
        return r;
    }
    const Grid& g = labels.grid;
    const auto [nx, ny, nz] = g.dims;
    DisjointSets<std::int32_t> sets(n);
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t p = g.index(i, j, k);
                const std::int32_t m = labels.material[p];
                if (m == 0) continue;
                // the 13 neighbours after p in x-fastest order
                for (int q = 14; q < 27; ++q) {
                    const int x = i + q % 3 - 1, y = j + q / 3 % 3 - 1, z = k + q / 9 - 1;
                    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
                    const std::size_t o = g.index(x, y, z);
                    if (labels.material[o] != m) continue;
                    sets.unite(static_cast<std::int32_t>(p), static_cast<std::int32_t>(o));
                }
            }
    std::map<std::int32_t, std::int32_t> dense;
    for (std::size_t p = 0; p < n; ++p)
        if (labels.material[p] != 0) {
            auto [it, fresh] = dense.emplace(sets.find(static_cast<std::int32_t>(p)), static_cast<std::int32_t>(dense.size()));
            r.id[p] = it->second;
        }
    r.regions.reset(dense.size());
    return r;
}

}  // namespace

RepairReport repairNonManifold(Labels& labels, const Domain& domain, const std::vector<std::int32_t>* regions,
                               const CellEdgeGroups* marchingCubes) {
    RepairReport rep;
    const Grid& g = labels.grid;
    const auto [nx, ny, nz] = g.dims;
    RegionIds ids = initialRegions(labels, regions);
    std::vector<std::uint8_t> flips(labels.material.size(), 0);
    bool plain = false;  // no topology preference (see the end of a round)
    constexpr int kMaxRounds = 200;
    // Pockets and specks can step back and forth between two contacts for a
    // few rounds before they settle (ch2bet); 6 flips per point instead of 4
    // gives them more rounds before a point is frozen (ch2bet 1 mm: chi 848
    // against 844, volumeToMesh of the scan 878; 8 to 16 give the same).
    constexpr int kMaxFlipsPerPoint = 6;
    auto isBorder = [&](int pi, int pj, int pk) {
        return pi == 0 || pj == 0 || pk == 0 || pi == nx - 1 || pj == ny - 1 || pk == nz - 1;
    };
    auto record = [&](std::size_t p, std::int32_t to) {
        if (labels.material[p] == 0) ++rep.pointsAdded;
        else if (to == 0) ++rep.pointsRemoved;
        else ++rep.pointsAdded;
        flipPoint(labels, ids, p, to);
        ++flips[p];
    };
    // A block can only turn bad when one of its points changes, so after the
    // first full scan each round looks at the blocks still bad and the blocks
    // around the points the previous round changed (the same set a full scan finds).
    std::vector<std::size_t> bad = badBlocks(labels);
    for (int round = 0;; ++round) {
        if (round > 0) bad = badBlocksAmong(labels, std::move(bad));
        if (round == 0) rep.nonManifoldBefore = bad.size();
        if (bad.empty()) {
            rep.rounds = round;
            return rep;
        }
        if (round == kMaxRounds)
            throw Error("non-manifold repair found no fixpoint after " + std::to_string(kMaxRounds) + " rounds (" +
                        std::to_string(bad.size()) + " bad places left); try a different --size or --iso");
        std::set<std::size_t> touched;  // points changed this round; their blocks wait for the next round
        std::vector<std::size_t> unionOnly;  // blocks with no flip to try where only the union is bad
        for (std::size_t b : bad) {
            const int i = static_cast<int>(b % nx), j = static_cast<int>(b / nx % ny), k = static_cast<int>(b / nx / ny);
            BlockView v = block(labels, i, j, k);
            bool stale = false;
            for (std::size_t p : v.point) stale = stale || touched.count(p);
            if (stale) continue;
            const int badNow = badness(v.mat), badMaterialsNow = badMaterials(v.mat);
            // Candidates: give one corner to another material present in the block (or background).
            std::vector<std::int32_t> present(v.mat.begin(), v.mat.end());
            present.push_back(0);
            std::sort(present.begin(), present.end());
            present.erase(std::unique(present.begin(), present.end()), present.end());
            double bestCost = 0;
            int bestCorner = -1, bestScore = 1 << 30;
            bool bestKeeps = false, bestSimple = false;
            int bestTier = -1;
            std::int32_t bestMat = 0;
            for (int c = 0; c < 8; ++c) {
                const int pi = i + (c & 1), pj = j + (c >> 1 & 1), pk = k + (c >> 2 & 1);
                const bool border = isBorder(pi, pj, pk);
                if (flips[v.point[c]] >= kMaxFlipsPerPoint) continue;
                const Vec3 x = g.point(pi, pj, pk);
                for (std::int32_t t : present) {
                    if (t == v.mat[c] || (border && t != 0)) continue;
                    auto trial = v.mat;
                    trial[c] = t;
                    // a flip mends the block when fewer materials (or their
                    // complements) are split in it, or fewer are bad at all
                    const int score = badness(trial);
                    if (score >= badNow && badMaterials(trial) >= badMaterialsNow) continue;
                    const std::int32_t judged = t != 0 ? t : v.mat[c];
                    const double cost = std::abs(domain.value(judged, x));
                    // Among flips that mend the block, prefer those that keep
                    // the topology of the surface marching cubes draws
                    // (simpleFlip), then those that mend it most, then those
                    // that keep every region's Euler characteristic, then the
                    // one nearest the surface.
                    const int tier = plain ? 0 : flipTier(labels, ids, pi, pj, pk, v.mat[c], t, marchingCubes);
                    const bool simple = tier == (marchingCubes ? 3 : 2);
                    const bool keepsEuler = (v.mat[c] == 0 || eulerChange(labels, pi, pj, pk, v.mat[c], false) == 0) &&
                                            (t == 0 || eulerChange(labels, pi, pj, pk, t, true) == 0);
                    const bool better =
                        bestCorner < 0 || tier > bestTier ||
                        (tier == bestTier &&
                         (score < bestScore || (score == bestScore && keepsEuler > bestKeeps) ||
                          (score == bestScore && keepsEuler == bestKeeps && cost < bestCost)));
                    if (better) {
                        bestScore = score;
                        bestKeeps = keepsEuler;
                        bestSimple = simple;
                        bestTier = tier;
                        bestCost = cost;
                        bestCorner = c;
                        bestMat = t;
                    }
                }
            }
            // No single flip keeps the topology (a pocket or a speck of one
            // point touching another along an edge): move it first. A
            // 6-neighbour y of corner c that has the material c is to take
            // takes c's material (simple), then c flips (simple); e.g. a
            // one-point pocket of the outside steps away from the pocket it
            // touches instead of being filled.
            std::size_t prepPoint = 0;
            std::int32_t prepMat = 0;
            bool prep = false;
            if (!bestSimple && !plain) {
                double bestMove = 0;
                for (int c = 0; c < 8; ++c) {
                    const int pi = i + (c & 1), pj = j + (c >> 1 & 1), pk = k + (c >> 2 & 1);
                    if (flips[v.point[c]] >= kMaxFlipsPerPoint) continue;
                    const std::int32_t from = v.mat[c];
                    for (std::int32_t t : present) {
                        if (t == from || (isBorder(pi, pj, pk) && t != 0)) continue;
                        for (int d = 0; d < 6; ++d) {
                            const int yi = pi + (d == 0) - (d == 1), yj = pj + (d == 2) - (d == 3),
                                      yk = pk + (d == 4) - (d == 5);
                            if (yi < 0 || yj < 0 || yk < 0 || yi >= nx || yj >= ny || yk >= nz) continue;
                            if (from != 0 && isBorder(yi, yj, yk)) continue;
                            const std::size_t y = g.index(yi, yj, yk);
                            if (labels.material[y] != t || flips[y] >= kMaxFlipsPerPoint) continue;
                            if (!simpleFlip(labels, ids, yi, yj, yk, t, from, marchingCubes)) continue;
                            const std::int32_t keepId = ids.id[y];
                            const std::size_t keepRegions = ids.regions.size();
                            flipPoint(labels, ids, y, from);
                            const BlockView w = block(labels, i, j, k);
                            auto trial = w.mat;
                            trial[c] = t;
                            const bool ok = badness(trial) < badNow && simpleFlip(labels, ids, pi, pj, pk, from, t, marchingCubes);
                            labels.material[y] = t;  // undo (y's new neighbours were one region: no merge)
                            ids.id[y] = keepId;
                            ids.regions.truncate(keepRegions);
                            if (!ok) continue;
                            const double cost = std::abs(domain.value(t != 0 ? t : from, g.point(pi, pj, pk))) +
                                                std::abs(domain.value(from != 0 ? from : t, g.point(yi, yj, yk)));
                            if (!prep || cost < bestMove) {
                                prep = true;
                                bestMove = cost;
                                prepPoint = y;
                                prepMat = from;
                                bestCorner = c;
                                bestMat = t;
                            }
                        }
                    }
                }
            }
            if (prep) {
                record(prepPoint, prepMat);
                touched.insert(prepPoint);
            }
            if (bestCorner < 0) {
                // No single flip makes this block better (e.g. a checkerboard):
                // grow the first bad material by its cheapest neighbour point.
                // Growing is monotone, so repeated rounds cannot cycle.
                std::int32_t grow = 0;
                for (int c = 0; c < 8 && grow == 0; ++c) {
                    unsigned p = 0;
                    for (int d = 0; d < 8; ++d)
                        if (v.mat[d] == v.mat[c]) p |= 1u << d;
                    if (v.mat[c] != 0 && !kTable.ok[p]) grow = v.mat[c];
                }
                if (grow == 0) {
                    unionOnly.push_back(b);
                    continue;
                }
                for (int c = 0; c < 8; ++c) {
                    if (v.mat[c] == grow) continue;
                    const int pi = i + (c & 1), pj = j + (c >> 1 & 1), pk = k + (c >> 2 & 1);
                    if (isBorder(pi, pj, pk)) continue;
                    const double cost = std::abs(domain.value(grow, g.point(pi, pj, pk)));
                    if (bestCorner < 0 || cost < bestCost) {
                        bestCorner = c;
                        bestCost = cost;
                        bestMat = grow;
                    }
                }
                if (bestCorner < 0) continue;
            }
            const std::size_t p = v.point[bestCorner];
            record(p, bestMat);
            touched.insert(p);
        }
        if (touched.empty() && plain) {
            // Last resort, where nothing else is left: every material is fine
            // on its own in these blocks but their union is not (points of
            // two materials touching along an edge or at a vertex with the
            // outside around them), and the points have used up their flips
            // trading places (the JHU atlas with --smooth 0.5 to 1.5 stopped
            // here). The outside grows: in each block the point nearest its
            // surface leaves, whatever its flips. Only reached when no other
            // rule changes anything (in plain mode; the topology preference
            // first gives way below); kMaxRounds still bounds the loop.
            for (std::size_t b : unionOnly) {
                const auto [i, j, k] = g.coords(b);
                const BlockView v = block(labels, i, j, k);
                bool stale = false;
                for (std::size_t q : v.point) stale = stale || touched.count(q);
                if (stale || blockManifold(v.mat)) continue;
                int best = -1;
                double bestCost = 0;
                for (int c = 0; c < 8; ++c) {
                    if (v.mat[c] == 0) continue;
                    const double cost =
                        std::abs(domain.value(v.mat[c], g.point(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))));
                    if (best < 0 || cost < bestCost) {
                        best = c;
                        bestCost = cost;
                    }
                }
                if (best < 0) continue;
                record(v.point[best], 0);
                touched.insert(v.point[best]);
            }
        }
        for (std::size_t p : touched) {
            const auto [i, j, k] = g.coords(p);
            for (int c = 0; c < 8; ++c) {
                const int bi = i - (c & 1), bj = j - (c >> 1 & 1), bk = k - (c >> 2 & 1);
                if (bi >= 0 && bj >= 0 && bk >= 0) bad.push_back(g.index(bi, bj, bk));
            }
        }
        if (touched.empty() && !plain) {
            // The topology preference can spend points' flips going back and
            // forth (random labellings of several materials): from here on,
            // the plain rules with fresh flips.
            plain = true;
            std::fill(flips.begin(), flips.end(), 0);
            continue;
        }
        if (touched.empty())
            throw Error("non-manifold repair is stuck: " + std::to_string(bad.size()) +
                        " places where regions touch along an edge or at a point cannot be fixed by flipping grid "
                        "points; try a different --size");
    }
}

std::vector<RegionTopology> regionTopology(const Labels& l) {
    const auto [nx, ny, nz] = l.grid.dims;
    // Every point pair, square and block is counted at the block whose lowest
    // corner is its lowest point; the grid's outer layer is background, so
    // nothing mixed is lost past the last block. Uniform blocks (almost all)
    // are skipped after one look at their corners.
    struct Acc {
        std::map<std::int32_t, RegionTopology> t;
        std::vector<std::pair<std::int32_t, std::size_t>> mixed;  // (material, block)
    };
    tbb::enumerable_thread_specific<Acc> local;
    tbb::parallel_for(tbb::blocked_range<int>(0, std::max(nz - 1, 0)), [&](const tbb::blocked_range<int>& r) {
        Acc& acc = local.local();
        for (int k = r.begin(); k != r.end(); ++k)
            for (int j = 0; j + 1 < ny; ++j)
                for (int i = 0; i + 1 < nx; ++i) {
                    const BlockView b = block(l, i, j, k);
                    if (uniformBlock(b.mat)) continue;
                    forBlockEuler(b.mat, [&](std::int32_t m, int d, bool wholeBlock) {
                        auto& t = acc.t[m];
                        t.material = m;
                        t.euler += d;
                        if (wholeBlock) acc.mixed.emplace_back(m, l.grid.index(i, j, k));
                    });
                }
    });
    std::map<std::int32_t, RegionTopology> out;
    for (std::int32_t m : l.material)
        if (m != 0) {
            auto& t = out[m];
            t.material = m;
            ++t.points;
        }
    std::vector<std::pair<std::int32_t, std::size_t>> mixed;
    for (auto& acc : local) {
        for (auto& [m, t] : acc.t) {
            out[m].material = m;
            out[m].euler += t.euler;
        }
        mixed.insert(mixed.end(), acc.mixed.begin(), acc.mixed.end());
    }
    std::sort(mixed.begin(), mixed.end());
    DisjointSets<std::size_t> sets(mixed.size());
    for (std::size_t n = 0; n < mixed.size(); ++n) {
        const auto [m, b] = mixed[n];
        const int i = static_cast<int>(b % nx), j = static_cast<int>(b / nx % ny), k = static_cast<int>(b / nx / ny);
        // neighbour block in +d shares the square of the block's far face in d
        for (int d = 0; d < 3; ++d) {
            const int ni = i + (d == 0), nj = j + (d == 1), nk = k + (d == 2);
            if (ni + 1 >= nx || nj + 1 >= ny || nk + 1 >= nz) continue;
            bool present = false, all = true;
            for (int c = 0; c < 8; ++c) {
                if (!(c >> d & 1)) continue;
                const std::int32_t mm = l.material[l.grid.index(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))];
                present = present || mm == m;
                all = all && mm == m;
            }
            if (!present || all) continue;
            const auto it = std::lower_bound(mixed.begin(), mixed.end(), std::make_pair(m, l.grid.index(ni, nj, nk)));
            if (it == mixed.end() || it->first != m) continue;
            const std::size_t other = static_cast<std::size_t>(it - mixed.begin());
            sets.unite(n, other);
        }
    }
    for (std::size_t n = 0; n < mixed.size(); ++n)
        if (sets.isRoot(n)) ++out[mixed[n].first].components;
    std::vector<RegionTopology> v;
    for (auto& [m, t] : out) v.push_back(t);
    return v;
}

std::string describe(const std::vector<RegionTopology>& t) {
    std::ostringstream s;
    for (std::size_t i = 0; i < t.size(); ++i) {
        if (i) s << "; ";
        s << "material " << t[i].material << ": " << t[i].components << " surface component"
          << (t[i].components == 1 ? "" : "s") << ", Euler characteristic " << t[i].euler;
    }
    return s.str();
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

}  // namespace isohex::octree

namespace isohex::octree {

std::vector<PointEdit> editNearInvertedHexes(Labels& labels, const std::vector<std::array<double, 3>>& positions,
                                             const std::vector<std::size_t>& frozen, int maxSame) {
    const Grid& g = labels.grid;
    const auto [nx, ny, nz] = g.dims;
    std::vector<PointEdit> edits;
    if (nx < 3 || ny < 3 || nz < 3) return edits;
    auto& mat = labels.material;
    auto isFrozen = [&](std::size_t p) { return std::find(frozen.begin(), frozen.end(), p) != frozen.end(); };
    const int faceStep[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    // Whether point (i, j, k) leaving material `from` for `to` keeps the
    // components, tunnels and cavities of both (simple for each: its
    // neighbours of that material one 26-component, the rest one 6-component
    // in the 18-neighbourhood) and leaves the 8 blocks around it manifold.
    auto allowed = [&](int i, int j, int k, std::int32_t from, std::int32_t to) {
        std::array<std::int32_t, 27> m27;
        for (int q = 0; q < 27; ++q)
            m27[q] = mat[g.index(i + q % 3 - 1, j + q / 3 % 3 - 1, k + q / 9 - 1)];
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
        // a point joining or leaving the object: the union of all materials
        // (and so the background: its pockets, the exterior) keeps its topology too
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
    };
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
                        if ((best && !(key < *best)) || !allowed(i, j, k, from, to)) continue;
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

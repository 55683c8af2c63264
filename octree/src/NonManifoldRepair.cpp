// Non-manifold repair: flips of grid points, chosen block by block and round
// by round, until every region and interface is manifold.
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <string>

#include "DigitalTopology.hpp"
#include "GridBlocks.hpp"
#include "PolygonWindow.hpp"
#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/Regions.hpp"
#include "isohex/octree/TopologyMatch.hpp"

namespace isohex::octree {

namespace {

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

// Region ids for the repair: the given ones, or each material's 26-connected
// components (points touching along an edge or at a corner in one region),
// numbered densely in the order of their first point.
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
    DisjointSets<std::uint32_t> sets = materialRegions(labels, Adjacency::Full);
    std::map<std::uint32_t, std::int32_t> dense;
    for (std::size_t p = 0; p < n; ++p)
        if (labels.material[p] != 0) {
            auto [it, fresh] = dense.emplace(sets.find(static_cast<std::uint32_t>(p)), static_cast<std::int32_t>(dense.size()));
            r.id[p] = it->second;
        }
    r.regions.reset(dense.size());
    return r;
}

constexpr int kMaxRounds = 200;
// Pockets and specks can step back and forth between two contacts for a few
// rounds before they settle; 6 flips per point instead of 4 gives them more
// rounds before a point is frozen (on a brain mask at 1 mm the boundary's
// Euler characteristic then comes closer to the polygoniser's; 8 to 16 give
// the same).
constexpr int kMaxFlipsPerPoint = 6;

// A non-manifold 2x2x2 block being mended: its lowest corner, its points and
// labels, how bad it is, and the materials its corners may take.
struct BadBlock {
    std::size_t b;
    int i, j, k;
    BlockView v;
    int badNow, badMaterialsNow;
    std::vector<std::int32_t> present;  // the block's materials and background, ascending

    BadBlock(const Labels& labels, std::size_t lowest) : b(lowest) {
        const auto [bi, bj, bk] = labels.grid.coords(lowest);
        i = bi, j = bj, k = bk;
        v = block(labels, i, j, k);
        badNow = badness(v.mat);
        badMaterialsNow = badMaterials(v.mat);
        present.assign(v.mat.begin(), v.mat.end());
        present.push_back(0);
        std::sort(present.begin(), present.end());
        present.erase(std::unique(present.begin(), present.end()), present.end());
    }
    // Grid coordinates of corner c.
    std::array<int, 3> corner(int c) const { return {i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1)}; }
};

// One corner of a bad block taking material `to`, with what ranks it.
struct FlipChoice {
    int corner = -1;      // -1: none
    std::int32_t to = 0;
    double cost = 0;      // |field| at the point (nearest the surface first)
    int score = 1 << 30;  // the block's badness after the flip
    bool keepsEuler = false, simple = false;
    int tier = -1;        // flipTier
};

// A pocket or speck moved by one point before a corner's flip: point
// `point` takes `mat`, then corner `corner` takes `to`.
struct PocketMove {
    std::size_t point;
    std::int32_t mat;
    int corner;
    std::int32_t to;
};

// The repair's state across rounds: the labels and their region ids, how
// often each point was flipped, and what the current round changed.
class Repair {
public:
    Repair(Labels& labels, const Domain& domain, const std::vector<std::int32_t>* regions, const CellEdgeGroups* mc)
        : labels_(labels), domain_(domain), mc_(mc), g_(labels.grid), ids_(initialRegions(labels, regions)),
          flips_(labels.material.size(), 0) {}

    // Rounds over the bad blocks until none is left (see repairNonManifold).
    RepairReport run();

private:
    Labels& labels_;
    const Domain& domain_;
    const CellEdgeGroups* mc_;
    const Grid& g_;
    RegionIds ids_;
    std::vector<std::uint8_t> flips_;  // per point: flips so far (frozen at kMaxFlipsPerPoint)
    bool plain_ = false;               // no topology preference (see run)
    RepairReport rep_;
    std::vector<std::size_t> bad_;       // blocks to look at this round (lowest corners)
    std::set<std::size_t> touched_;      // points changed this round; their blocks wait for the next round
    std::vector<std::size_t> unionOnly_; // blocks with no flip to try where only the union is bad

    bool isBorder(int i, int j, int k) const {
        const auto [nx, ny, nz] = g_.dims;
        return i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1;
    }
    bool frozen(std::size_t p) const { return flips_[p] >= kMaxFlipsPerPoint; }
    bool stale(const BlockView& v) const {
        bool s = false;
        for (std::size_t p : v.point) s = s || touched_.count(p);
        return s;
    }
    // Point p takes material `to`: counted, flipped with its region id, and
    // held back from further blocks this round.
    void record(std::size_t p, std::int32_t to) {
        if (labels_.material[p] == 0) ++rep_.pointsAdded;
        else if (to == 0) ++rep_.pointsRemoved;
        else ++rep_.pointsAdded;
        flipPoint(labels_, ids_, p, to);
        ++flips_[p];
        touched_.insert(p);
    }

    FlipChoice bestFlip(const BadBlock& bb);
    bool pocketMoveMends(const BadBlock& bb, int c, std::size_t y, std::int32_t t);
    std::optional<PocketMove> pocketMove(const BadBlock& bb);
    FlipChoice growChoice(const BadBlock& bb, bool& onlyUnion) const;
    void mendBlock(std::size_t b);
    void shrinkUnionOnly();
    void queueBlocksAroundTouched();
};

// Among the single flips that mend the block (fewer materials, or their
// complements, split in it, or fewer bad at all), the one that keeps the
// topology of the surface marching cubes draws (simpleFlip), then mends it
// most, then keeps every region's Euler characteristic, then lies nearest
// the surface.
FlipChoice Repair::bestFlip(const BadBlock& bb) {
    FlipChoice best;
    for (int c = 0; c < 8; ++c) {
        const auto [pi, pj, pk] = bb.corner(c);
        const bool border = isBorder(pi, pj, pk);
        if (frozen(bb.v.point[c])) continue;
        const Vec3 x = g_.point(pi, pj, pk);
        const std::int32_t from = bb.v.mat[c];
        for (std::int32_t t : bb.present) {
            if (t == from || (border && t != 0)) continue;
            auto trial = bb.v.mat;
            trial[c] = t;
            const int score = badness(trial);
            if (score >= bb.badNow && badMaterials(trial) >= bb.badMaterialsNow) continue;
            const double cost = std::abs(domain_.value(t != 0 ? t : from, x));
            const int tier = plain_ ? 0 : flipTier(labels_, ids_, pi, pj, pk, from, t, mc_);
            const bool simple = tier == (mc_ ? 3 : 2);
            const bool keepsEuler = (from == 0 || eulerChange(labels_, pi, pj, pk, from, false) == 0) &&
                                    (t == 0 || eulerChange(labels_, pi, pj, pk, t, true) == 0);
            const bool better =
                best.corner < 0 || tier > best.tier ||
                (tier == best.tier &&
                 (score < best.score || (score == best.score && keepsEuler > best.keepsEuler) ||
                  (score == best.score && keepsEuler == best.keepsEuler && cost < best.cost)));
            if (better) best = FlipChoice{c, t, cost, score, keepsEuler, simple, tier};
        }
    }
    return best;
}

// Whether point y (a 6-neighbour of corner c holding `t`) taking corner c's
// material, and then corner c taking t, mends the block with two simple
// flips. Tried and undone (y's new neighbours are one region: no merge).
bool Repair::pocketMoveMends(const BadBlock& bb, int c, std::size_t y, std::int32_t t) {
    const std::int32_t from = bb.v.mat[c];
    const auto [pi, pj, pk] = bb.corner(c);
    const std::int32_t keepId = ids_.id[y];
    const std::size_t keepRegions = ids_.regions.size();
    flipPoint(labels_, ids_, y, from);
    const BlockView w = block(labels_, bb.i, bb.j, bb.k);
    auto trial = w.mat;
    trial[c] = t;
    const bool ok = badness(trial) < bb.badNow && simpleFlip(labels_, ids_, pi, pj, pk, from, t, mc_);
    labels_.material[y] = t;
    ids_.id[y] = keepId;
    ids_.regions.truncate(keepRegions);
    return ok;
}

// No single flip keeps the topology (a pocket or a speck of one point
// touching another along an edge): move it first. A 6-neighbour y of corner
// c that has the material c is to take takes c's material (simple), then c
// flips (simple); e.g. a one-point pocket of the outside steps away from the
// pocket it touches instead of being filled. The cheapest such move (|field|
// at both points).
std::optional<PocketMove> Repair::pocketMove(const BadBlock& bb) {
    const auto [nx, ny, nz] = g_.dims;
    std::optional<PocketMove> best;
    double bestMove = 0;
    for (int c = 0; c < 8; ++c) {
        const auto [pi, pj, pk] = bb.corner(c);
        if (frozen(bb.v.point[c])) continue;
        const std::int32_t from = bb.v.mat[c];
        for (std::int32_t t : bb.present) {
            if (t == from || (isBorder(pi, pj, pk) && t != 0)) continue;
            for (int d = 0; d < 6; ++d) {
                const int yi = pi + (d == 0) - (d == 1), yj = pj + (d == 2) - (d == 3), yk = pk + (d == 4) - (d == 5);
                if (yi < 0 || yj < 0 || yk < 0 || yi >= nx || yj >= ny || yk >= nz) continue;
                if (from != 0 && isBorder(yi, yj, yk)) continue;
                const std::size_t y = g_.index(yi, yj, yk);
                if (labels_.material[y] != t || frozen(y)) continue;
                if (!simpleFlip(labels_, ids_, yi, yj, yk, t, from, mc_)) continue;
                if (!pocketMoveMends(bb, c, y, t)) continue;
                const double cost = std::abs(domain_.value(t != 0 ? t : from, g_.point(pi, pj, pk))) +
                                    std::abs(domain_.value(from != 0 ? from : t, g_.point(yi, yj, yk)));
                if (!best || cost < bestMove) {
                    bestMove = cost;
                    best = PocketMove{y, from, c, t};
                }
            }
        }
    }
    return best;
}

// No single flip makes the block better (e.g. a checkerboard): grow the
// first bad material by its cheapest neighbour point. Growing is monotone,
// so repeated rounds cannot cycle. onlyUnion: no material is bad on its own
// (only their union is), so there is nothing to grow.
FlipChoice Repair::growChoice(const BadBlock& bb, bool& onlyUnion) const {
    std::int32_t grow = 0;
    for (int c = 0; c < 8 && grow == 0; ++c) {
        unsigned p = 0;
        for (int d = 0; d < 8; ++d)
            if (bb.v.mat[d] == bb.v.mat[c]) p |= 1u << d;
        if (bb.v.mat[c] != 0 && !kTable.ok[p]) grow = bb.v.mat[c];
    }
    onlyUnion = grow == 0;
    FlipChoice best;
    if (onlyUnion) return best;
    for (int c = 0; c < 8; ++c) {
        if (bb.v.mat[c] == grow) continue;
        const auto [pi, pj, pk] = bb.corner(c);
        if (isBorder(pi, pj, pk)) continue;
        const double cost = std::abs(domain_.value(grow, g_.point(pi, pj, pk)));
        if (best.corner < 0 || cost < best.cost) {
            best.corner = c;
            best.cost = cost;
            best.to = grow;
        }
    }
    return best;
}

// One bad block of a round: its best flip, preceded by a pocket move where
// no single flip keeps the topology, or else the growth of a bad material.
// Blocks with a point changed earlier this round wait for the next.
void Repair::mendBlock(std::size_t b) {
    const BadBlock bb(labels_, b);
    if (stale(bb.v)) return;
    FlipChoice best = bestFlip(bb);
    if (!best.simple && !plain_) {
        if (const auto move = pocketMove(bb)) {
            record(move->point, move->mat);
            best.corner = move->corner;
            best.to = move->to;
        }
    }
    if (best.corner < 0) {
        bool onlyUnion = false;
        best = growChoice(bb, onlyUnion);
        if (onlyUnion) {
            unionOnly_.push_back(b);
            return;
        }
        if (best.corner < 0) return;
    }
    record(bb.v.point[best.corner], best.to);
}

// Last resort, where nothing else is left: every material is fine on its own
// in these blocks but their union is not (points of two materials touching
// along an edge or at a vertex with the outside around them), and the points
// have used up their flips trading places (smoothed label atlases stopped
// here). The outside grows: in each block the point nearest its surface
// leaves, whatever its flips. Only reached when no other rule changes
// anything (in plain mode; the topology preference first gives way in run);
// kMaxRounds still bounds the loop.
void Repair::shrinkUnionOnly() {
    for (std::size_t b : unionOnly_) {
        const auto [i, j, k] = g_.coords(b);
        const BlockView v = block(labels_, i, j, k);
        if (stale(v) || blockManifold(v.mat)) continue;
        int best = -1;
        double bestCost = 0;
        for (int c = 0; c < 8; ++c) {
            if (v.mat[c] == 0) continue;
            const double cost = std::abs(domain_.value(v.mat[c], g_.point(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))));
            if (best < 0 || cost < bestCost) {
                best = c;
                bestCost = cost;
            }
        }
        if (best >= 0) record(v.point[best], 0);
    }
}

// A block can only turn bad when one of its points changes, so after the
// first full scan each round looks at the blocks still bad and the blocks
// around the points the previous round changed (the same set a full scan finds).
void Repair::queueBlocksAroundTouched() {
    for (std::size_t p : touched_) {
        const auto [i, j, k] = g_.coords(p);
        for (int c = 0; c < 8; ++c) {
            const int bi = i - (c & 1), bj = j - (c >> 1 & 1), bk = k - (c >> 2 & 1);
            if (bi >= 0 && bj >= 0 && bk >= 0) bad_.push_back(g_.index(bi, bj, bk));
        }
    }
}

RepairReport Repair::run() {
    bad_ = badBlocks(labels_);
    for (int round = 0;; ++round) {
        if (round > 0) bad_ = badBlocksAmong(labels_, std::move(bad_));
        if (round == 0) rep_.nonManifoldBefore = bad_.size();
        if (bad_.empty()) {
            rep_.rounds = round;
            return rep_;
        }
        if (round == kMaxRounds)
            throw SettingError({"non-manifold repair found no fixpoint after " + std::to_string(kMaxRounds) +
                                    " rounds (" + std::to_string(bad_.size()) + " bad places left); try a different ",
                                Setting::Size, " or ", Setting::Iso});
        touched_.clear();
        unionOnly_.clear();
        for (std::size_t b : bad_) mendBlock(b);
        if (touched_.empty() && plain_) shrinkUnionOnly();
        queueBlocksAroundTouched();
        if (touched_.empty() && !plain_) {
            // The topology preference can spend points' flips going back and
            // forth (random labellings of several materials): from here on,
            // the plain rules with fresh flips.
            plain_ = true;
            std::fill(flips_.begin(), flips_.end(), 0);
            continue;
        }
        if (touched_.empty())
            throw SettingError({"non-manifold repair is stuck: " + std::to_string(bad_.size()) +
                                    " places where regions touch along an edge or at a point cannot be fixed by "
                                    "flipping grid points; try a different ",
                                Setting::Size});
    }
}

}  // namespace

std::size_t countNonManifoldBlocks(const Labels& labels) { return badBlocks(labels).size(); }

RepairReport repairNonManifold(Labels& labels, const Domain& domain, const std::vector<std::int32_t>* regions,
                               const CellEdgeGroups* marchingCubes) {
    return Repair(labels, domain, regions, marchingCubes).run();
}

}  // namespace isohex::octree

// Keeping the polygoniser's surface topology through the repair
// (matchPolygonTopology) and the exact single-flip test.
#include "isohex/octree/TopologyMatch.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "GridBlocks.hpp"
#include "PolygonWindow.hpp"
#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/octree/DualContour.hpp"

namespace isohex::octree {

bool flipKeepsPolygonTopology(const Labels& labels, int i, int j, int k, std::int32_t to, const CellEdgeGroups& table,
                              long long* eulerChange) {
    const std::int32_t from = labels.material[labels.grid.index(i, j, k)];
    if (from == to) {
        if (eulerChange) *eulerChange = 0;
        return true;
    }
    long long dFrom = 0, dTo = 0;
    const bool keepsFrom = from == 0 || mcKeeps(labels, i, j, k, from, table, &dFrom);
    const bool keepsTo = to == 0 || mcKeeps(labels, i, j, k, to, table, &dTo);
    if (eulerChange) *eulerChange = dFrom + dTo;
    return keepsFrom && keepsTo;
}

namespace {

// Euler characteristic of the boundary of the union of the cubes around
// every material's points (regionTopology's sum), counted over the blocks
// with lowest corners `blocks`.
long long cubeEuler(const Labels& l, const std::vector<std::size_t>& blocks) {
    long long chi = 0;
    for (std::size_t b : blocks) {
        const auto [i, j, k] = l.grid.coords(b);
        const BlockView v = block(l, i, j, k);
        if (!uniformBlock(v.mat)) forBlockEuler(v.mat, [&](std::int32_t, int d, bool) { chi += d; });
    }
    return chi;
}

// matchPolygonTopology's search: at most this many flips on top of the
// repair's change, and this many trials per search (a bound on the time a
// noisy place can take: three flips among 80 options are 82,160 trials).
constexpr int kMatchDepth = 3;
constexpr std::size_t kMatchTrials = 150'000;
// The deep search (for what the flip search cannot mend): flips of boundary
// points within kDeepReach of the group, kDeepBeam sets kept per round, at
// most kDeepDepth flips and kDeepTrials trials; a unit of topology distance
// weighs as much as kDeepTopologyWeight bad blocks; a beam stops after
// kDeepPatience rounds without a better best score.
constexpr int kDeepReach = 2;
constexpr std::size_t kDeepBeam = 12;
constexpr int kDeepDepth = 10;
constexpr std::size_t kDeepTrials = 40'000;
constexpr long long kDeepTopologyWeight = 4;
constexpr int kDeepPatience = 2;
// The annealing after a beam that found nothing: up to kAnnealChains chains
// of kAnnealSteps steps, the temperature falling from kAnnealT0 to kAnnealT1
// (in units of the deep search's score), each option on costing
// kAnnealOptionCost; at most kAnnealBudget steps in one run.
constexpr int kAnnealChains = 6;
constexpr long kAnnealSteps = 10'000;
constexpr double kAnnealT0 = 1.5, kAnnealT1 = 0.5, kAnnealOptionCost = 2;
constexpr std::size_t kAnnealBudget = 120'000;

// Lowest corners of the blocks holding any of the points, sorted, unique (into out).
void blocksAround(const Grid& g, const std::vector<std::size_t>& points, std::vector<std::size_t>& out) {
    const auto [nx, ny, nz] = g.dims;
    out.clear();
    for (std::size_t p : points) {
        const auto [i, j, k] = g.coords(p);
        for (int c = 0; c < 8; ++c) {
            const int bi = i - (c & 1), bj = j - (c >> 1 & 1), bk = k - (c >> 2 & 1);
            if (bi >= 0 && bj >= 0 && bk >= 0 && bi + 1 < nx && bj + 1 < ny && bk + 1 < nz)
                out.push_back(g.index(bi, bj, bk));
        }
    }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
}

std::vector<std::size_t> blocksAround(const Grid& g, const std::vector<std::size_t>& points) {
    std::vector<std::size_t> out;
    blocksAround(g, points, out);
    return out;
}

// Whether the change keeps every involved material's polygoniser surface;
// *eulerChange: the sum of their Euler changes.
bool changeKeepsPolygonTopology(const Labels& l, const std::vector<PointChange>& changes, const CellEdgeGroups& t,
                                long long* eulerChange) {
    std::vector<std::int32_t> mats;
    for (const auto& [p, to] : changes) {
        if (l.material[p] == to) continue;
        if (l.material[p] != 0) mats.push_back(l.material[p]);
        if (to != 0) mats.push_back(to);
    }
    std::sort(mats.begin(), mats.end());
    mats.erase(std::unique(mats.begin(), mats.end()), mats.end());
    bool keeps = true;
    long long sum = 0;
    for (std::int32_t m : mats) {
        long long d = 0;
        keeps = mcKeeps(l, changes, m, t, &d) && keeps;
        sum += d;
    }
    if (eulerChange) *eulerChange = sum;
    return keeps;
}

}  // namespace

TopologyMatchReport matchPolygonTopology(Labels& repaired, const Labels& sampled, const Domain& domain,
                                         const CellEdgeGroups& table) {
    TopologyMatchReport rep;
    const Grid& g = repaired.grid;
    const auto [nx, ny, nz] = g.dims;
    if (sampled.material.size() != repaired.material.size())
        throw Error("matchPolygonTopology: the sampled and repaired labels have different grids");
    std::vector<std::size_t> changed;
    for (std::size_t p = 0; p < repaired.material.size(); ++p)
        if (repaired.material[p] != sampled.material[p]) changed.push_back(p);
    if (changed.empty()) return rep;
    auto coords = [&](std::size_t p) { return g.coords(p); };
    // Groups: changed points within kGap of each other on every axis. A
    // group's search flips points within 1 of it, or within 2 where no
    // point of another group is next to the flip; so a block holding a flip
    // holds no point of another group, and a block holding flips of two
    // groups is checked by the later group's search.
    constexpr int kGap = 2;
    std::unordered_map<std::size_t, std::int32_t> at;
    at.reserve(changed.size() * 2);
    for (std::size_t n = 0; n < changed.size(); ++n) at.emplace(changed[n], static_cast<std::int32_t>(n));
    DisjointSets<std::int32_t> groups(changed.size());
    for (std::size_t n = 0; n < changed.size(); ++n) {
        const auto [i, j, k] = coords(changed[n]);
        for (int dz = -kGap; dz <= kGap; ++dz)
            for (int dy = -kGap; dy <= kGap; ++dy)
                for (int dx = -kGap; dx <= kGap; ++dx) {
                    const int x = i + dx, y = j + dy, z = k + dz;
                    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
                    const auto it = at.find(g.index(x, y, z));
                    if (it != at.end() && it->second > static_cast<std::int32_t>(n))
                        groups.unite(static_cast<std::int32_t>(n), it->second);
                }
    }
    std::map<std::int32_t, std::vector<std::size_t>> members;  // by root: the smallest member, in grid order
    for (std::size_t n = 0; n < changed.size(); ++n)
        members[groups.find(static_cast<std::int32_t>(n))].push_back(changed[n]);
    rep.groups = members.size();

    Labels work = sampled;
    auto isBorder = [&](const std::array<int, 3>& c) {
        return c[0] == 0 || c[1] == 0 || c[2] == 0 || c[0] == nx - 1 || c[1] == ny - 1 || c[2] == nz - 1;
    };
    auto apply = [&](const std::vector<PointChange>& ch) {
        for (const auto& [p, to] : ch) work.material[p] = to;
    };
    auto manifoldAt = [&](const std::vector<std::size_t>& blocks) {
        for (std::size_t b : blocks) {
            const auto [i, j, k] = g.coords(b);
            const BlockView v = block(work, i, j, k);
            if (!uniformBlock(v.mat) && !blockManifold(v.mat)) return false;
        }
        return true;
    };
    // The points within 1 of `points`, sorted.
    // Whether a changed point of another group lies within 1 of (x, y, z)
    // (not on the grid's border).
    auto nextToOtherGroup = [&](int x, int y, int z, std::int32_t group) {
        for (int q = 0; q < 27; ++q) {
            const auto it = at.find(g.index(x + q % 3 - 1, y + q / 3 % 3 - 1, z + q / 9 - 1));
            if (it != at.end() && groups.find(it->second) != group) return true;
        }
        return false;
    };
    auto around = [&](const std::vector<std::size_t>& points) {
        std::vector<std::size_t> near;
        for (std::size_t p : points) {
            const auto [i, j, k] = coords(p);
            for (int dz = -1; dz <= 1; ++dz)
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int x = i + dx, y = j + dy, z = k + dz;
                        if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
                        near.push_back(g.index(x, y, z));
                    }
        }
        std::sort(near.begin(), near.end());
        near.erase(std::unique(near.begin(), near.end()), near.end());
        return near;
    };
    constexpr int kMaxExtent = 12;   // wider groups are split, or keep the repair's change
    constexpr std::size_t kDeepOptions = 80;  // three flips only around small groups (options^3)

    // Search: up to kMatchDepth flips of points within 1 of the group, on top
    // of the repair's change (already applied), that leave every block around
    // them manifold and make the whole change (from `before`) keep the
    // polygoniser's surface. Applies the best one; false if none.
    // later/laterBefore (optional): points still to be changed after this
    // one, as the repair changes them and as they are now; the blocks are
    // judged with them changed, the surface with them as they are.
    auto search = [&](std::int32_t group, const std::vector<std::size_t>& near, const std::vector<PointChange>& before,
                      const std::vector<PointChange>& change, long long d0,
                      const std::vector<PointChange>* later = nullptr,
                      const std::vector<PointChange>* laterBefore = nullptr,
                      const std::unordered_set<std::size_t>* frozen = nullptr, int maxDepth = kMatchDepth) {
        // of the later points, those a block around a flip can hold (within
        // 1 of `near`): set and reset on every trial
        std::vector<PointChange> laterHere, laterHereBefore;
        if (later) {
            const std::vector<std::size_t> reach = around(near);
            for (std::size_t n = 0; n < later->size(); ++n)
                if (std::binary_search(reach.begin(), reach.end(), (*later)[n].first)) {
                    laterHere.push_back((*later)[n]);
                    laterHereBefore.push_back((*laterBefore)[n]);
                }
        }
        std::vector<PointChange> options;  // (point, material it may take)
        for (std::size_t p : near) {
            const auto c = coords(p);
            if (isBorder(c) || (frozen && frozen->count(p))) continue;
            if (nextToOtherGroup(c[0], c[1], c[2], group)) continue;
            std::vector<std::int32_t> to{0, sampled.material[p], repaired.material[p]};
            for (int d = 0; d < 6; ++d) {
                const int x = c[0] + (d == 0) - (d == 1), y = c[1] + (d == 2) - (d == 3), z = c[2] + (d == 4) - (d == 5);
                to.push_back(work.material[g.index(x, y, z)]);
            }
            std::sort(to.begin(), to.end());
            to.erase(std::unique(to.begin(), to.end()), to.end());
            for (std::int32_t m : to)
                if (m != work.material[p]) options.emplace_back(p, m);
        }
        bool found = false;
        std::vector<PointChange> best;
        std::size_t bestDiff = 0;
        double bestCost = 0;
        std::vector<int> pick;
        std::vector<PointChange> flips, undo;  // reused by every trial
        std::vector<std::size_t> flipped, blocks;
        std::size_t trials = 0;
        auto evaluate = [&]() {
            ++trials;
            flips.clear();
            undo.clear();
            flipped.clear();
            for (int q : pick) {
                flips.push_back(options[q]);
                flipped.push_back(options[q].first);
                undo.emplace_back(options[q].first, work.material[options[q].first]);
            }
            blocksAround(g, flipped, blocks);
            apply(laterHere);
            apply(flips);
            // Where both states are manifold the polygoniser's surface changes
            // its Euler characteristic as the cubes' boundary does: a cheap
            // filter before the exact test.
            bool candidate = manifoldAt(blocks);
            if (candidate) {
                const long long chi = cubeEuler(work, blocks);
                apply(undo);
                candidate = chi - cubeEuler(work, blocks) == -d0;
                apply(flips);
            }
            apply(laterHereBefore);
            if (candidate) {
                std::vector<PointChange> total;
                for (const auto& [p, was] : before)
                    if (work.material[p] != was) total.emplace_back(p, work.material[p]);
                apply(before);
                const bool keeps = changeKeepsPolygonTopology(work, total, table, nullptr);
                apply(change);
                apply(flips);
                if (keeps) {
                    std::size_t diff = 0;
                    double cost = 0;
                    for (const auto& [p, to] : total) {
                        if (to == sampled.material[p]) continue;
                        ++diff;
                        const auto c = coords(p);
                        cost += std::abs(domain.value(to != 0 ? to : sampled.material[p], g.point(c[0], c[1], c[2])));
                    }
                    if (!found || diff < bestDiff || (diff == bestDiff && cost < bestCost)) {
                        found = true;
                        best = flips;
                        bestDiff = diff;
                        bestCost = cost;
                    }
                }
            }
            apply(undo);
        };
        for (int depth = 1; depth <= maxDepth && !found; ++depth) {
            if (depth == 3 && options.size() > kDeepOptions) break;
            pick.assign(depth, 0);
            // combinations of `depth` options at distinct points, in order
            std::function<void(int, int)> choose = [&](int level, int from) {
                if (trials >= kMatchTrials) return;
                if (level == depth) {
                    evaluate();
                    return;
                }
                for (int q = from; q < static_cast<int>(options.size()); ++q) {
                    bool clash = false;
                    for (int e = 0; e < level; ++e) clash = clash || options[pick[e]].first == options[q].first;
                    if (clash) continue;
                    pick[level] = q;
                    choose(level + 1, q + 1);
                }
            };
            choose(0, 0);
        }
        if (found) apply(best);
        return found;
    };

    // One group: its change as the repair made it when that keeps the
    // surface; else the search's. A group too wide for the search is taken
    // part by part (see below); it keeps the repair's change whole if its
    // parts leave a block around it bad.
    auto extentOf = [&](const std::vector<std::size_t>& points) {
        std::array<int, 3> lo{nx, ny, nz}, hi{-1, -1, -1};
        for (std::size_t p : points) {
            const auto c = coords(p);
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], c[a]);
                hi[a] = std::max(hi[a], c[a]);
            }
        }
        return std::array<int, 6>{lo[0], lo[1], lo[2], hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1};
    };
    auto place = [&](const std::vector<std::size_t>& points, long long d0) {
        const auto box = extentOf(points);
        TopologyMatchReport::Place pl;
        pl.lo = {box[0], box[1], box[2]};
        pl.hi = {box[0] + box[3] - 1, box[1] + box[4] - 1, box[2] + box[5] - 1};
        pl.points = points.size();
        pl.eulerChange = d0;
        rep.unmended.push_back(pl);
    };
    auto changeOf = [&](const std::vector<std::size_t>& points) {
        std::vector<PointChange> change;
        for (std::size_t p : points) change.emplace_back(p, repaired.material[p]);
        return change;
    };
    // Deep search, for a group (or part) the flip search could not mend: a
    // beam search over sets of flips of points within kDeepReach of it
    // (points on a material boundary, none next to another group or in
    // `frozen`), on top of the repair's change. A set is scored by how far
    // the polygon surface in a window around the box is from what it was
    // before the group (McProbe, per material) and by the blocks it leaves
    // bad. Each round extends the kDeepBeam best sets by one flip; the first
    // round with a set that leaves every block manifold and keeps the surface
    // (then checked again exactly, as in search) ends it, the set nearest the
    // sampled labels winning. A beam whose best score has not improved for
    // kDeepPatience rounds stops, as does one past kDeepDepth flips or
    // kDeepTrials probed sets. later/laterBefore as in search.
    // what the deep search flipped (point, material before), in order: its
    // box can reach beyond the points within 2 of the group
    std::vector<PointChange> deepFlipped;
    auto deepSearch = [&](std::int32_t group, const std::vector<std::size_t>& points,
                          const std::vector<PointChange>* later = nullptr,
                          const std::vector<PointChange>* laterBefore = nullptr,
                          const std::unordered_set<std::size_t>* frozen = nullptr) {
        const auto box = extentOf(points);
        std::array<int, 3> lo{}, hi{};
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::max(box[a] - kDeepReach, 1);
            hi[a] = std::min(box[a] + box[3 + a] - 1 + kDeepReach, g.dims[a] - 2);
        }
        // the box and 1 around it (the points its blocks hold), as they are
        // now (`after`, the group changed) and were before the group
        std::vector<PointChange> after;
        for (int z = lo[2] - 1; z <= hi[2] + 1; ++z)
            for (int y = lo[1] - 1; y <= hi[1] + 1; ++y)
                for (int x = lo[0] - 1; x <= hi[0] + 1; ++x) {
                    const std::size_t p = g.index(x, y, z);
                    after.emplace_back(p, work.material[p]);
                }
        std::vector<PointChange> before = after;
        {
            const std::unordered_set<std::size_t> inGroup(points.begin(), points.end());
            for (auto& [p, m] : before)
                if (inGroup.count(p)) m = sampled.material[p];
        }
        // Options: flips of points on a material boundary in the box, none
        // next to another group or in `frozen`; and moves that isolate a
        // one-point piece (speck or pocket) of the sampled labels: the point
        // takes its sampled material and its 26 neighbours that have that
        // material take the one most of its 6 neighbours have in the sampled
        // labels (no sequence of single flips reaches that without passing
        // through states that score worse); or the piece moved: a point
        // within 2 of it whose 26 neighbours all have one other material
        // takes its material (a piece of one point there is manifold). One
        // option is one step.
        auto allowed = [&](int x, int y, int z) {
            if (x < lo[0] || y < lo[1] || z < lo[2] || x > hi[0] || y > hi[1] || z > hi[2]) return false;
            return !(frozen && frozen->count(g.index(x, y, z))) && !nextToOtherGroup(x, y, z, group);
        };
        std::vector<std::vector<PointChange>> options;
        for (int z = lo[2]; z <= hi[2]; ++z)
            for (int y = lo[1]; y <= hi[1]; ++y)
                for (int x = lo[0]; x <= hi[0]; ++x) {
                    if (!allowed(x, y, z)) continue;
                    const std::size_t p = g.index(x, y, z);
                    bool boundary = false;
                    std::vector<std::int32_t> to{0, sampled.material[p], repaired.material[p]};
                    std::map<std::int32_t, int> sampled6;  // the sampled materials of the 6 neighbours
                    for (int q = 0; q < 27; ++q) {
                        const std::size_t o = g.index(x + q % 3 - 1, y + q / 3 % 3 - 1, z + q / 9 - 1);
                        boundary = boundary || work.material[o] != work.material[p];
                        if (q == 4 || q == 10 || q == 12 || q == 14 || q == 16 || q == 22) {
                            to.push_back(work.material[o]);
                            ++sampled6[sampled.material[o]];
                        }
                    }
                    if (boundary) {
                        std::sort(to.begin(), to.end());
                        to.erase(std::unique(to.begin(), to.end()), to.end());
                        for (std::int32_t m : to)
                            if (m != work.material[p]) options.push_back({PointChange{p, m}});
                    }
                    const std::int32_t m = sampled.material[p];
                    if (sampled6.count(m)) continue;  // not a one-point piece
                    std::int32_t around = 0;
                    int most = -1;
                    for (const auto& [mat, n] : sampled6)
                        if (n > most) {
                            most = n;
                            around = mat;
                        }
                    std::vector<PointChange> move;
                    if (work.material[p] != m) move.emplace_back(p, m);
                    bool ok = true;
                    for (int q = 0; q < 27 && ok; ++q) {
                        const int a = x + q % 3 - 1, b = y + q / 3 % 3 - 1, c = z + q / 9 - 1;
                        const std::size_t o = g.index(a, b, c);
                        if (q == 13 || work.material[o] != m) continue;
                        ok = allowed(a, b, c);
                        move.emplace_back(o, around);
                    }
                    if (ok && move.size() > 1) options.push_back(std::move(move));
                    // the piece moved
                    for (int q = 0; q < 125; ++q) {
                        const int a = x + q % 5 - 2, b = y + q / 5 % 5 - 2, c = z + q / 25 - 2;
                        if (!allowed(a, b, c) || work.material[g.index(a, b, c)] == m) continue;
                        bool interior = true;
                        const std::int32_t here = work.material[g.index(a, b, c)];
                        for (int r = 0; r < 27 && interior; ++r)
                            interior = work.material[g.index(a + r % 3 - 1, b + r / 3 % 3 - 1, c + r / 9 - 1)] == here;
                        if (interior) options.push_back({PointChange{g.index(a, b, c), m}});
                    }
                }
        // (a point can be offered twice, from two pieces: keep one)
        std::sort(options.begin(), options.end());
        options.erase(std::unique(options.begin(), options.end()), options.end());
        // The materials whose surface is judged: those the group's change or
        // an option gives or takes a point
        std::vector<std::int32_t> mats;
        for (std::size_t p : points) mats.insert(mats.end(), {sampled.material[p], repaired.material[p]});
        for (const auto& o : options)
            for (const auto& [p, to] : o) mats.insert(mats.end(), {work.material[p], to});
        std::sort(mats.begin(), mats.end());
        mats.erase(std::unique(mats.begin(), mats.end()), mats.end());
        apply(before);
        std::vector<std::unique_ptr<McProbe>> probes;
        for (std::int32_t m : mats)
            if (m != 0) probes.push_back(std::make_unique<McProbe>(work, lo, hi, m, table));
        apply(after);
        // Bad blocks are counted as the flips change them: the box's blocks
        // bad now, plus the change in the blocks around a set's flips. Later
        // parts of a wide group in the box are changed as the repair changes
        // them when blocks are judged, and left as they are for the surface.
        std::vector<PointChange> laterHere, laterHereBefore;
        if (later)
            for (std::size_t n = 0; n < later->size(); ++n) {
                const auto c = coords((*later)[n].first);
                bool in = true;
                for (int a = 0; a < 3; ++a) in = in && c[a] >= lo[a] - 1 && c[a] <= hi[a] + 1;
                if (!in) continue;
                laterHere.push_back((*later)[n]);
                laterHereBefore.push_back((*laterBefore)[n]);
            }
        auto isBad = [&](std::size_t b) {
            const auto [i, j, k] = g.coords(b);
            const BlockView v = block(work, i, j, k);
            return !uniformBlock(v.mat) && !blockManifold(v.mat);
        };
        std::vector<std::size_t> optionPoints(points);
        for (const auto& o : options)
            for (const auto& pc : o) optionPoints.push_back(pc.first);
        std::unordered_set<std::size_t> baseBad;
        apply(laterHere);
        for (std::size_t b : blocksAround(g, optionPoints))
            if (isBad(b)) baseBad.insert(b);
        apply(laterHereBefore);
        struct Trial {
            std::vector<int> pick;  // option indices, ascending
            long long score = 0;
            std::size_t diff = 0;   // points off the sampled labels that were not before
            double cost = 0;        // |field| at those
        };
        std::vector<std::size_t> flipped, blocks;
        std::vector<PointChange> undo;
        std::size_t trials = 0;
        // Scores t; false (not probed) when it has more bad blocks than
        // `threshold` (its score is at least that). goal: manifold and the
        // surface kept exactly.
        auto evaluate = [&](Trial& t, bool& goal, long long threshold) {
            goal = false;
            flipped.clear();
            undo.clear();
            for (int q : t.pick)
                for (const auto& [p, to] : options[q]) {
                    flipped.push_back(p);
                    undo.emplace_back(p, work.material[p]);
                    work.material[p] = to;
                }
            blocksAround(g, flipped, blocks);
            long long bad = static_cast<long long>(baseBad.size());
            apply(laterHere);
            for (std::size_t b : blocks) bad += static_cast<long long>(isBad(b)) - static_cast<long long>(baseBad.count(b));
            apply(laterHereBefore);
            if (bad > threshold) {
                apply(undo);
                return false;
            }
            ++trials;
            long long dist = 0;
            for (auto& pr : probes) dist += pr->distance();
            t.score = dist * kDeepTopologyWeight + bad;
            t.diff = 0;
            t.cost = 0;
            for (const auto& [p, was] : before) {
                const std::int32_t to = work.material[p];
                if (to == was || to == sampled.material[p]) continue;
                ++t.diff;
                const auto c = coords(p);
                t.cost += std::abs(domain.value(to != 0 ? to : sampled.material[p], g.point(c[0], c[1], c[2])));
            }
            if (dist == 0 && bad == 0) {
                std::vector<PointChange> total;
                for (const auto& [p, was] : before)
                    if (work.material[p] != was) total.emplace_back(p, work.material[p]);
                apply(before);
                goal = changeKeepsPolygonTopology(work, total, table, nullptr);
                apply(total);
            }
            apply(undo);
            return true;
        };
        // applies a winning set (recorded for the wide-group fallback)
        auto take = [&](const Trial& won) {
            for (int q : won.pick)
                for (const auto& [p, to] : options[q]) {
                    deepFlipped.emplace_back(p, work.material[p]);
                    work.material[p] = to;
                }
            rep.deepTrials += trials;
            return true;
        };
        auto ranks = [](const Trial& a, const Trial& b) {
            return std::tie(a.score, a.diff, a.cost, a.pick) < std::tie(b.score, b.diff, b.cost, b.pick);
        };
        std::vector<Trial> beam(1);
        std::set<std::vector<int>> seen;
        long long bestSoFar = std::numeric_limits<long long>::max();
        int lastGain = 0;
        for (int depth = 1; depth <= kDeepDepth && trials < kDeepTrials; ++depth) {
            std::vector<Trial> next, goals;
            std::multiset<long long> top;  // the kDeepBeam best scores of this round so far
            for (const Trial& from : beam)
                for (int q = 0; q < static_cast<int>(options.size()) && trials < kDeepTrials; ++q) {
                    bool clash = false;
                    for (int e : from.pick)
                        for (const auto& a : options[e])
                            for (const auto& b : options[q]) clash = clash || a.first == b.first;
                    if (clash) continue;
                    Trial t;
                    t.pick = from.pick;
                    t.pick.insert(std::upper_bound(t.pick.begin(), t.pick.end(), q), q);
                    if (!seen.insert(t.pick).second) continue;
                    bool goal = false;
                    const long long threshold =
                        top.size() < kDeepBeam ? std::numeric_limits<long long>::max() : *top.rbegin();
                    if (!evaluate(t, goal, threshold)) continue;
                    if (goal) {
                        goals.push_back(std::move(t));
                        continue;
                    }
                    top.insert(t.score);
                    if (top.size() > kDeepBeam) top.erase(std::prev(top.end()));
                    next.push_back(std::move(t));
                }
            if (!goals.empty()) {
                const Trial& best = *std::min_element(goals.begin(), goals.end(), [](const Trial& a, const Trial& b) {
                    return std::tie(a.diff, a.cost, a.pick) < std::tie(b.diff, b.cost, b.pick);
                });
                return take(best);
            }
            if (next.empty()) break;
            const long long bestNow = std::min_element(next.begin(), next.end(), ranks)->score;
            if (bestNow < bestSoFar) {
                bestSoFar = bestNow;
                lastGain = depth;
            } else if (depth - lastGain >= kDeepPatience) {
                break;
            }
            const std::size_t keep = std::min<std::size_t>(kDeepBeam, next.size());
            std::partial_sort(next.begin(), next.begin() + static_cast<std::ptrdiff_t>(keep), next.end(), ranks);
            next.resize(keep);
            beam = std::move(next);
        }
        // Annealing, when the beam found nothing: chains of random single
        // toggles of options (on or off), accepted by the Metropolis rule on
        // score + kAnnealOptionCost per option on, at a temperature falling
        // from kAnnealT0 to kAnnealT1; a chain that reaches a goal (checked
        // exactly) has its set shrunk (options dropped, one or two at a time,
        // while it stays a goal) and applied. Chains are seeded by their
        // number; the run's budget is spent in grid order, so the result
        // depends on the input only (not on the thread count).
        std::vector<std::vector<std::int32_t>> onWas(options.size());  // materials an option replaced
        std::unordered_map<std::size_t, int> takenBy;
        std::vector<std::vector<std::size_t>> blocksOf(options.size());  // the blocks around an option, when first drawn
        auto badIn = [&](const std::vector<std::size_t>& bs) {
            long long n = 0;
            apply(laterHere);
            for (std::size_t b2 : bs) n += isBad(b2);
            apply(laterHereBefore);
            return n;
        };
        auto toggle = [&](int q) {  // (switched on only when no point of it is taken)
            if (!onWas[q].empty()) {
                for (std::size_t n = 0; n < options[q].size(); ++n) {
                    work.material[options[q][n].first] = onWas[q][n];
                    takenBy.erase(options[q][n].first);
                }
                onWas[q].clear();
                return;
            }
            for (const auto& [p, to] : options[q]) {
                onWas[q].push_back(work.material[p]);
                takenBy.emplace(p, q);
                work.material[p] = to;
            }
        };
        for (int chain = 0; chain < kAnnealChains && !options.empty() && rep.annealSteps < kAnnealBudget; ++chain) {
            std::mt19937 rng(static_cast<std::uint32_t>(chain + 1));
            long long bad = static_cast<long long>(baseBad.size()), dist = 0;
            for (auto& pr : probes) dist += pr->distance();
            long long picks = 0;
            bool reached = false;
            Trial t;
            for (long step = 0; step < kAnnealSteps && rep.annealSteps < kAnnealBudget; ++step) {
                ++rep.annealSteps;
                const double T = kAnnealT0 * std::pow(kAnnealT1 / kAnnealT0, static_cast<double>(step) / static_cast<double>(kAnnealSteps));
                const int q = static_cast<int>(rng() % options.size());
                const bool wasOn = !onWas[q].empty();
                bool clash = false;
                for (const auto& pc : options[q]) clash = clash || (!wasOn && takenBy.count(pc.first) > 0);
                if (clash) continue;
                if (blocksOf[q].empty()) {
                    std::vector<std::size_t> pts;
                    for (const auto& pc : options[q]) pts.push_back(pc.first);
                    blocksAround(g, pts, blocksOf[q]);
                }
                const long long b0 = badIn(blocksOf[q]);
                toggle(q);
                const long long b1 = badIn(blocksOf[q]);
                long long d = 0;
                for (auto& pr : probes) d += pr->distance();
                const long long newBad = bad - b0 + b1, newPicks = picks + (wasOn ? -1 : 1);
                if (d == 0 && newBad == 0) {
                    // checked exactly from the state before the group; a set
                    // the probes pass but the exact test does not is kept
                    // and the chain goes on from it
                    t.pick.clear();
                    for (int o = 0; o < static_cast<int>(options.size()); ++o)
                        if (!onWas[o].empty()) t.pick.push_back(o);
                    for (int o : t.pick) toggle(o);
                    bool goal = false;
                    evaluate(t, goal, std::numeric_limits<long long>::max());
                    if (goal) {
                        reached = true;
                        break;
                    }
                    for (int o : t.pick) toggle(o);
                    bad = newBad;
                    dist = d;
                    picks = newPicks;
                    continue;
                }
                const double dE = static_cast<double>((d - dist) * kDeepTopologyWeight + (newBad - bad)) +
                                  kAnnealOptionCost * static_cast<double>(newPicks - picks);
                const std::uint32_t r = rng();
                if (dE <= 0 || static_cast<double>(r) < std::exp(-dE / T) * 4294967296.0) {
                    bad = newBad;
                    dist = d;
                    picks = newPicks;
                } else {
                    toggle(q);
                }
            }
            if (!reached) {
                for (int o = static_cast<int>(options.size()) - 1; o >= 0; --o)
                    if (!onWas[o].empty()) toggle(o);
                continue;
            }
            // t without options n (and n2 > n, if given); true, and t that
            // set, when it is still a goal
            auto dropped = [&](std::size_t n, std::size_t n2) {
                Trial u;
                u.pick = t.pick;
                if (n2 < u.pick.size()) u.pick.erase(u.pick.begin() + static_cast<std::ptrdiff_t>(n2));
                u.pick.erase(u.pick.begin() + static_cast<std::ptrdiff_t>(n));
                bool still = false;
                evaluate(u, still, 0);
                if (still) t = std::move(u);
                return still;
            };
            for (bool shrunk = true; shrunk;) {
                shrunk = false;
                for (std::size_t n = 0; n < t.pick.size();)
                    if (dropped(n, t.pick.size())) shrunk = true;
                    else ++n;
                for (std::size_t n = 0; n < t.pick.size() && !shrunk; ++n)
                    for (std::size_t n2 = n + 1; n2 < t.pick.size() && !shrunk; ++n2) shrunk = dropped(n, n2);
            }
            return take(t);
        }
        rep.deepTrials += trials;
        return false;
    };
    auto process = [&](std::int32_t group, const std::vector<std::size_t>& points) {
        deepFlipped.clear();
        const std::vector<PointChange> change = changeOf(points);
        const auto box = extentOf(points);
        const bool wide = std::max({box[3], box[4], box[5]}) > kMaxExtent;
        const std::vector<std::size_t> near = around(points), near2 = around(near);
        if (!wide) {
            long long d0 = 0;
            if (changeKeepsPolygonTopology(work, change, table, &d0)) {
                apply(change);
                return;
            }
            ++rep.groupsChanging;
            std::vector<PointChange> before;  // the state before the group, at the points it may touch
            for (std::size_t p : near2) before.emplace_back(p, work.material[p]);
            apply(change);
            // points next to the group first; then within 2, with two flips at most
            if (search(group, near, before, change, d0) ||
                search(group, near2, before, change, d0, nullptr, nullptr, nullptr, 2) ||
                deepSearch(group, points))
                ++rep.groupsMatched;
            else
                place(points, d0);
            return;
        }
        std::vector<PointChange> before;
        for (std::size_t p : near2) before.emplace_back(p, work.material[p]);
        // 26-connected parts of a wide group, in grid order
        std::unordered_map<std::size_t, std::int32_t> index;
        for (std::size_t n = 0; n < points.size(); ++n) index.emplace(points[n], static_cast<std::int32_t>(n));
        DisjointSets<std::int32_t> parts(points.size());
        for (std::size_t n = 0; n < points.size(); ++n) {
            const auto [i, j, k] = coords(points[n]);
            for (int q = 0; q < 27; ++q) {
                const int x = i + q % 3 - 1, y = j + q / 3 % 3 - 1, z = k + q / 9 - 1;
                if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
                const auto it = index.find(g.index(x, y, z));
                if (it != index.end()) parts.unite(static_cast<std::int32_t>(n), it->second);
            }
        }
        std::map<std::int32_t, std::vector<std::size_t>> byPart;
        for (std::size_t n = 0; n < points.size(); ++n) byPart[parts.find(static_cast<std::int32_t>(n))].push_back(points[n]);
        // The parts in turn, each checked from the state the earlier ones
        // left (so the group keeps the surface when every part does); a
        // part's search judges blocks with the later parts changed as the
        // repair changes them.
        // a part wider than the search is cut into boxes 8 points wide
        std::vector<std::vector<std::size_t>> order;
        for (const auto& [r, part] : byPart) {
            const auto pbox = extentOf(part);
            if (std::max({pbox[3], pbox[4], pbox[5]}) <= kMaxExtent) {
                order.push_back(part);
                continue;
            }
            std::map<std::array<int, 3>, std::vector<std::size_t>> chunks;
            for (std::size_t p : part) {
                const auto c = coords(p);
                chunks[{(c[2] - pbox[2]) / 8, (c[1] - pbox[1]) / 8, (c[0] - pbox[0]) / 8}].push_back(p);
            }
            for (auto& [key, chunk] : chunks) order.push_back(std::move(chunk));
        }
        const std::unordered_set<std::size_t> groupPoints(points.begin(), points.end());
        bool changing = false, mended = true;
        const std::size_t placesBefore = rep.unmended.size();
        for (std::size_t n = 0; n < order.size(); ++n) {
            const std::vector<std::size_t>& part = order[n];
            const std::vector<PointChange> partChange = changeOf(part);
            const std::vector<std::size_t> partNear = around(part), partNear2 = around(partNear);
            std::vector<PointChange> partBefore;
            for (std::size_t p : partNear2) partBefore.emplace_back(p, work.material[p]);
            long long dp = 0;
            const bool keeps = changeKeepsPolygonTopology(work, partChange, table, &dp);
            apply(partChange);
            if (keeps) continue;
            std::vector<PointChange> later, laterBefore;
            for (std::size_t m = n + 1; m < order.size(); ++m)
                for (std::size_t p : order[m]) {
                    later.emplace_back(p, repaired.material[p]);
                    laterBefore.emplace_back(p, work.material[p]);
                }
            std::unordered_set<std::size_t> frozen = groupPoints;  // the other parts' points
            for (std::size_t p : part) frozen.erase(p);
            changing = true;
            const bool found =
                search(group, partNear, partBefore, partChange, dp, &later, &laterBefore, &frozen) ||
                search(group, partNear2, partBefore, partChange, dp, &later, &laterBefore, &frozen, 2) ||
                deepSearch(group, part, &later, &laterBefore, &frozen);
            if (!found) place(part, dp);
            mended = mended && found;
        }
        if (changing) ++rep.groupsChanging;
        // the blocks around what changed (a flip is never next to another group)
        std::vector<std::size_t> touched = points;
        for (const auto& [p, was] : before)
            if (work.material[p] != was) touched.push_back(p);
        for (const auto& [p, was] : deepFlipped) touched.push_back(p);
        if (!manifoldAt(blocksAround(g, touched))) {
            // the whole group keeps the repair's change: one place for it
            for (auto it = deepFlipped.rbegin(); it != deepFlipped.rend(); ++it) work.material[it->first] = it->second;
            apply(before);
            long long d = 0;
            changeKeepsPolygonTopology(work, change, table, &d);
            apply(change);
            rep.unmended.resize(placesBefore);
            if (changing) place(points, d);
            mended = false;
        }
        if (changing && mended) ++rep.groupsMatched;
    };
    for (const auto& [root, points] : members) process(root, points);
    // Each search checked the blocks around its flips; the whole grid is
    // checked once more, and a result that is not manifold is not used.
    if (!badBlocks(work).empty()) {
        rep.groupsMatched = 0;
        rep.discarded = true;
        return rep;
    }
    std::size_t differ = 0;
    for (std::size_t p = 0; p < work.material.size(); ++p) differ += work.material[p] != repaired.material[p];
    rep.pointsChanged = differ;
    repaired.material = std::move(work.material);
    return rep;
}

}  // namespace isohex::octree

// Keeping the polygoniser's surface topology through the repair: the exact
// single-flip test, and matchPolygonTopology's grouping of the repair's
// changes, the mending of each group (the searches are in
// TopologyMatchFlips.cpp and TopologyMatchDeep.cpp) and the final check.
#include "isohex/octree/TopologyMatch.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "GridBlocks.hpp"
#include "PolygonWindow.hpp"
#include "TopologyMatchState.hpp"
#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/TopologyMatch.hpp"

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

long long cubeEuler(const Labels& l, const std::vector<std::size_t>& blocks) {
    long long chi = 0;
    for (std::size_t b : blocks) {
        const auto [i, j, k] = l.grid.coords(b);
        const BlockView v = block(l, i, j, k);
        if (!uniformBlock(v.mat)) forBlockEuler(v.mat, [&](std::int32_t, int d, bool) { chi += d; });
    }
    return chi;
}

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

// --- MatchState

int Extent::widest() const { return std::max({width(0), width(1), width(2)}); }

MatchState::MatchState(Labels& repaired_, const Labels& sampled_, const Domain& domain_, const CellEdgeGroups& table_)
    : repaired(repaired_), sampled(sampled_), domain(domain_), table(table_), g(repaired_.grid),
      nx(g.dims[0]), ny(g.dims[1]), nz(g.dims[2]) {}

bool MatchState::badBlock(std::size_t b) const {
    const auto [i, j, k] = g.coords(b);
    const BlockView v = block(work, i, j, k);
    return !uniformBlock(v.mat) && !blockManifold(v.mat);
}

bool MatchState::manifoldAt(const std::vector<std::size_t>& blocks) const {
    for (std::size_t b : blocks)
        if (badBlock(b)) return false;
    return true;
}

bool MatchState::nextToOtherGroup(int x, int y, int z, std::int32_t group) {
    for (int q = 0; q < 27; ++q) {
        const auto it = at.find(g.index(x + q % 3 - 1, y + q / 3 % 3 - 1, z + q / 9 - 1));
        if (it != at.end() && groups.find(it->second) != group) return true;
    }
    return false;
}

std::vector<std::size_t> MatchState::around(const std::vector<std::size_t>& points) const {
    std::vector<std::size_t> near;
    for (std::size_t p : points) {
        const auto [i, j, k] = g.coords(p);
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
}

Extent MatchState::extentOf(const std::vector<std::size_t>& points) const {
    Extent e{{nx, ny, nz}, {-1, -1, -1}};
    for (std::size_t p : points) {
        const auto c = g.coords(p);
        for (int a = 0; a < 3; ++a) {
            e.lo[a] = std::min(e.lo[a], c[a]);
            e.hi[a] = std::max(e.hi[a], c[a]);
        }
    }
    return e;
}

std::vector<PointChange> MatchState::changeOf(const std::vector<std::size_t>& points) const {
    std::vector<PointChange> change;
    for (std::size_t p : points) change.emplace_back(p, repaired.material[p]);
    return change;
}

std::vector<PointChange> MatchState::snapshot(const std::vector<std::size_t>& points) const {
    std::vector<PointChange> now;
    for (std::size_t p : points) now.emplace_back(p, work.material[p]);
    return now;
}

std::vector<PointChange> MatchState::changedSince(const std::vector<PointChange>& before) const {
    std::vector<PointChange> total;
    for (const auto& [p, was] : before)
        if (work.material[p] != was) total.emplace_back(p, work.material[p]);
    return total;
}

bool MatchState::keepsSince(const std::vector<PointChange>& before) {
    const std::vector<PointChange> total = changedSince(before);
    apply(before);
    const bool keeps = changeKeepsPolygonTopology(work, total, table, nullptr);
    apply(total);
    return keeps;
}

void MatchState::offSampled(const std::vector<PointChange>& before, std::size_t& diff, double& cost) const {
    diff = 0;
    cost = 0;
    for (const auto& [p, was] : before) {
        const std::int32_t to = work.material[p];
        if (to == was || to == sampled.material[p]) continue;
        ++diff;
        const auto c = g.coords(p);
        cost += std::abs(domain.value(to != 0 ? to : sampled.material[p], g.point(c[0], c[1], c[2])));
    }
}

void MatchState::reportUnmended(const std::vector<std::size_t>& points, long long eulerChange) {
    const Extent box = extentOf(points);
    TopologyMatchReport::Place pl;
    pl.lo = box.lo;
    pl.hi = box.hi;
    pl.points = points.size();
    pl.eulerChange = eulerChange;
    rep.unmended.push_back(pl);
}

namespace {

// Groups: changed points within kGap of each other on every axis. A group's
// search flips points within 1 of it, or within 2 where no point of another
// group is next to the flip; so a block holding a flip holds no point of
// another group, and a block holding flips of two groups is checked by the
// later group's search.
constexpr int kGap = 2;
// Wider groups are taken part by part, or keep the repair's change.
constexpr int kMaxExtent = 12;
// Parts wider than kMaxExtent are cut into boxes this many points wide.
constexpr int kChunk = 8;
// The flip search: at most this many flips of points next to the place,
// then at most kFarDepth of points within 2 of it.
constexpr int kNearDepth = 3;
constexpr int kFarDepth = 2;

// One run of matchPolygonTopology: its phases over the shared state.
class TopologyMatcher {
public:
    TopologyMatcher(Labels& repaired, const Labels& sampled, const Domain& domain, const CellEdgeGroups& table)
        : s_(repaired, sampled, domain, table) {}

    TopologyMatchReport run();

private:
    std::map<std::int32_t, std::vector<std::size_t>> groupChanges();
    void mendGroup(std::int32_t group, const std::vector<std::size_t>& points);
    void mendNarrowGroup(std::int32_t group, const std::vector<std::size_t>& points,
                         const std::vector<PointChange>& change, const std::vector<std::size_t>& near,
                         const std::vector<std::size_t>& near2);
    void mendWideGroup(std::int32_t group, const std::vector<std::size_t>& points,
                       const std::vector<PointChange>& change, const std::vector<std::size_t>& near2);
    std::vector<std::vector<std::size_t>> partsOf(const std::vector<std::size_t>& points);
    bool mend(const Target& t, const std::vector<std::size_t>& near, const std::vector<std::size_t>& near2);
    void applyIfManifold();

    MatchState s_;
};

// The run: group the changed points, mend each group in turn (in grid order
// of their smallest point, each from the state the earlier ones left), then
// keep the result only if the whole grid is manifold.
TopologyMatchReport TopologyMatcher::run() {
    if (s_.sampled.material.size() != s_.repaired.material.size())
        throw Error("matchPolygonTopology: the sampled and repaired labels have different grids");
    const auto members = groupChanges();
    if (members.empty()) return s_.rep;
    s_.rep.groups = members.size();
    s_.work = s_.sampled;
    for (const auto& [root, points] : members) mendGroup(root, points);
    applyIfManifold();
    return s_.rep;
}

// The changed points (where the repair differs from the sampled labels),
// united within kGap of each other; by root (the smallest member), each
// group's points in grid order.
std::map<std::int32_t, std::vector<std::size_t>> TopologyMatcher::groupChanges() {
    std::vector<std::size_t> changed;
    for (std::size_t p = 0; p < s_.repaired.material.size(); ++p)
        if (s_.repaired.material[p] != s_.sampled.material[p]) changed.push_back(p);
    std::map<std::int32_t, std::vector<std::size_t>> members;
    if (changed.empty()) return members;
    const Grid& g = s_.g;
    s_.at.reserve(changed.size() * 2);
    for (std::size_t n = 0; n < changed.size(); ++n) s_.at.emplace(changed[n], static_cast<std::int32_t>(n));
    s_.groups.reset(changed.size());
    for (std::size_t n = 0; n < changed.size(); ++n) {
        const auto [i, j, k] = g.coords(changed[n]);
        for (int dz = -kGap; dz <= kGap; ++dz)
            for (int dy = -kGap; dy <= kGap; ++dy)
                for (int dx = -kGap; dx <= kGap; ++dx) {
                    const int x = i + dx, y = j + dy, z = k + dz;
                    if (x < 0 || y < 0 || z < 0 || x >= s_.nx || y >= s_.ny || z >= s_.nz) continue;
                    const auto it = s_.at.find(g.index(x, y, z));
                    if (it != s_.at.end() && it->second > static_cast<std::int32_t>(n))
                        s_.groups.unite(static_cast<std::int32_t>(n), it->second);
                }
    }
    for (std::size_t n = 0; n < changed.size(); ++n)
        members[s_.groups.find(static_cast<std::int32_t>(n))].push_back(changed[n]);
    return members;
}

// One group: its change as the repair made it when that keeps the surface;
// else the searches'. A group wider than kMaxExtent is taken part by part.
void TopologyMatcher::mendGroup(std::int32_t group, const std::vector<std::size_t>& points) {
    s_.deepFlipped.clear();
    const std::vector<PointChange> change = s_.changeOf(points);
    const bool wide = s_.extentOf(points).widest() > kMaxExtent;
    const std::vector<std::size_t> near = s_.around(points), near2 = s_.around(near);
    if (wide) mendWideGroup(group, points, change, near2);
    else mendNarrowGroup(group, points, change, near, near2);
}

// The searches in turn, each tried only when the ones before found nothing:
// flips of points next to the place, then of points within 2 (fewer), then
// the deep search.
bool TopologyMatcher::mend(const Target& t, const std::vector<std::size_t>& near,
                           const std::vector<std::size_t>& near2) {
    return flipSearch(s_, t, near, kNearDepth) || flipSearch(s_, t, near2, kFarDepth) || deepSearch(s_, t);
}

// A group narrow enough for the searches: kept as the repair changed it when
// that keeps the polygon surface, else mended or listed as unmended.
void TopologyMatcher::mendNarrowGroup(std::int32_t group, const std::vector<std::size_t>& points,
                                      const std::vector<PointChange>& change, const std::vector<std::size_t>& near,
                                      const std::vector<std::size_t>& near2) {
    long long d0 = 0;
    if (changeKeepsPolygonTopology(s_.work, change, s_.table, &d0)) {
        s_.apply(change);
        return;
    }
    ++s_.rep.groupsChanging;
    const std::vector<PointChange> before = s_.snapshot(near2);  // the state before the group, where it may touch
    s_.apply(change);
    if (mend(Target{group, points, before, change, d0}, near, near2)) ++s_.rep.groupsMatched;
    else s_.reportUnmended(points, d0);
}

// The parts of a wide group in turn, each checked from the state the earlier
// ones left (so the group keeps the surface when every part does); a part's
// search judges blocks with the later parts changed as the repair changes
// them. If the parts leave a block around the group bad, the whole group
// keeps the repair's change and is one unmended place.
void TopologyMatcher::mendWideGroup(std::int32_t group, const std::vector<std::size_t>& points,
                                    const std::vector<PointChange>& change, const std::vector<std::size_t>& near2) {
    const std::vector<PointChange> before = s_.snapshot(near2);
    const std::vector<std::vector<std::size_t>> order = partsOf(points);
    const std::unordered_set<std::size_t> groupPoints(points.begin(), points.end());
    bool changing = false, mended = true;
    const std::size_t placesBefore = s_.rep.unmended.size();
    for (std::size_t n = 0; n < order.size(); ++n) {
        const std::vector<std::size_t>& part = order[n];
        const std::vector<PointChange> partChange = s_.changeOf(part);
        const std::vector<std::size_t> partNear = s_.around(part), partNear2 = s_.around(partNear);
        const std::vector<PointChange> partBefore = s_.snapshot(partNear2);
        long long dp = 0;
        const bool keeps = changeKeepsPolygonTopology(s_.work, partChange, s_.table, &dp);
        s_.apply(partChange);
        if (keeps) continue;
        std::vector<PointChange> later, laterBefore;
        for (std::size_t m = n + 1; m < order.size(); ++m)
            for (std::size_t p : order[m]) {
                later.emplace_back(p, s_.repaired.material[p]);
                laterBefore.emplace_back(p, s_.work.material[p]);
            }
        std::unordered_set<std::size_t> frozen = groupPoints;  // the other parts' points
        for (std::size_t p : part) frozen.erase(p);
        changing = true;
        const bool found =
            mend(Target{group, part, partBefore, partChange, dp, &later, &laterBefore, &frozen}, partNear, partNear2);
        if (!found) s_.reportUnmended(part, dp);
        mended = mended && found;
    }
    if (changing) ++s_.rep.groupsChanging;
    // the blocks around what changed (a flip is never next to another group)
    std::vector<std::size_t> touched = points;
    for (const auto& [p, was] : before)
        if (s_.work.material[p] != was) touched.push_back(p);
    for (const auto& [p, was] : s_.deepFlipped) touched.push_back(p);
    if (!s_.manifoldAt(blocksAround(s_.g, touched))) {
        // the whole group keeps the repair's change: one place for it
        for (auto it = s_.deepFlipped.rbegin(); it != s_.deepFlipped.rend(); ++it)
            s_.work.material[it->first] = it->second;
        s_.apply(before);
        long long d = 0;
        changeKeepsPolygonTopology(s_.work, change, s_.table, &d);
        s_.apply(change);
        s_.rep.unmended.resize(placesBefore);
        if (changing) s_.reportUnmended(points, d);
        mended = false;
    }
    if (changing && mended) ++s_.rep.groupsMatched;
}

// The 26-connected parts of a wide group in grid order, a part wider than
// kMaxExtent cut into boxes kChunk points wide (in z, y, x order).
std::vector<std::vector<std::size_t>> TopologyMatcher::partsOf(const std::vector<std::size_t>& points) {
    const Grid& g = s_.g;
    std::unordered_map<std::size_t, std::int32_t> index;
    for (std::size_t n = 0; n < points.size(); ++n) index.emplace(points[n], static_cast<std::int32_t>(n));
    DisjointSets<std::int32_t> parts(points.size());
    for (std::size_t n = 0; n < points.size(); ++n) {
        const auto [i, j, k] = g.coords(points[n]);
        for (int q = 0; q < 27; ++q) {
            const int x = i + q % 3 - 1, y = j + q / 3 % 3 - 1, z = k + q / 9 - 1;
            if (x < 0 || y < 0 || z < 0 || x >= s_.nx || y >= s_.ny || z >= s_.nz) continue;
            const auto it = index.find(g.index(x, y, z));
            if (it != index.end()) parts.unite(static_cast<std::int32_t>(n), it->second);
        }
    }
    std::map<std::int32_t, std::vector<std::size_t>> byPart;
    for (std::size_t n = 0; n < points.size(); ++n)
        byPart[parts.find(static_cast<std::int32_t>(n))].push_back(points[n]);
    std::vector<std::vector<std::size_t>> order;
    for (const auto& [r, part] : byPart) {
        const Extent box = s_.extentOf(part);
        if (box.widest() <= kMaxExtent) {
            order.push_back(part);
            continue;
        }
        std::map<std::array<int, 3>, std::vector<std::size_t>> chunks;
        for (std::size_t p : part) {
            const auto c = g.coords(p);
            chunks[{(c[2] - box.lo[2]) / kChunk, (c[1] - box.lo[1]) / kChunk, (c[0] - box.lo[0]) / kChunk}].push_back(p);
        }
        for (auto& [key, chunk] : chunks) order.push_back(std::move(chunk));
    }
    return order;
}

// Each search checked the blocks around its flips; the whole grid is checked
// once more, and a result that is not manifold is not used.
void TopologyMatcher::applyIfManifold() {
    if (!badBlocks(s_.work).empty()) {
        s_.rep.groupsMatched = 0;
        s_.rep.discarded = true;
        return;
    }
    std::size_t differ = 0;
    for (std::size_t p = 0; p < s_.work.material.size(); ++p)
        differ += s_.work.material[p] != s_.repaired.material[p];
    s_.rep.pointsChanged = differ;
    s_.repaired.material = std::move(s_.work.material);
}

}  // namespace

TopologyMatchReport matchPolygonTopology(Labels& repaired, const Labels& sampled, const Domain& domain,
                                         const CellEdgeGroups& table) {
    return TopologyMatcher(repaired, sampled, domain, table).run();
}

}  // namespace isohex::octree

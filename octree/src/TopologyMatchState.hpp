#pragma once
// The state one matchPolygonTopology run shares between its phases (private
// to octree/): the labels being chosen, the groups of changed points, the
// report, and the small operations every search of a place uses.
//
// The run: group the changed points (TopologyMatch.cpp), then per group in
// grid order check its change and, where it alters the polygon surface, mend
// it with the flip search (TopologyMatchFlips.cpp), then the deep search
// (TopologyMatchDeep.cpp: beam search, then annealing); finally check the
// whole grid and apply. Everything is single-threaded and deterministic.
#include <array>
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "PolygonWindow.hpp"
#include "isohex/core/DisjointSets.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/TopologyMatch.hpp"

namespace isohex::octree {

// Euler characteristic of the boundary of the union of the cubes around
// every material's points (regionTopology's sum), counted over the blocks
// with lowest corners `blocks`.
long long cubeEuler(const Labels& l, const std::vector<std::size_t>& blocks);

// Lowest corners of the blocks holding any of the points, sorted, unique (into out).
void blocksAround(const Grid& g, const std::vector<std::size_t>& points, std::vector<std::size_t>& out);
std::vector<std::size_t> blocksAround(const Grid& g, const std::vector<std::size_t>& points);

// Whether the change keeps every involved material's polygoniser surface;
// *eulerChange: the sum of their Euler changes.
bool changeKeepsPolygonTopology(const Labels& l, const std::vector<PointChange>& changes, const CellEdgeGroups& t,
                                long long* eulerChange);

// The box of a set of grid points: lowest and highest point on each axis.
struct Extent {
    std::array<int, 3> lo{}, hi{};
    int width(int a) const { return hi[a] - lo[a] + 1; }
    int widest() const;
};

// One place a search mends: a group of changed points, or a part of a wide
// group, with its change (the repair's) already applied to the work labels.
struct Target {
    std::int32_t group = 0;                 // the group's root (its points are not "another group")
    const std::vector<std::size_t>& points;
    const std::vector<PointChange>& before;  // the state before the change, at the points within 2
    const std::vector<PointChange>& change;  // the repair's change of `points`
    long long eulerChange = 0;               // what that change does to the polygon surface's Euler characteristic
    // Of a wide group's part: the later parts' points as the repair changes
    // them and as they are now (blocks are judged with them changed, the
    // surface with them as they are), and the other parts' points (never flipped).
    const std::vector<PointChange>* later = nullptr;
    const std::vector<PointChange>* laterBefore = nullptr;
    const std::unordered_set<std::size_t>* frozen = nullptr;
};

struct MatchState {
    MatchState(Labels& repaired, const Labels& sampled, const Domain& domain, const CellEdgeGroups& table);

    Labels& repaired;
    const Labels& sampled;
    const Domain& domain;
    const CellEdgeGroups& table;
    const Grid& g;
    const int nx, ny, nz;
    TopologyMatchReport rep;
    Labels work;                                    // the sampled labels, with the groups taken so far changed
    std::unordered_map<std::size_t, std::int32_t> at;  // changed point -> its number
    DisjointSets<std::int32_t> groups;              // over the changed points' numbers
    std::vector<PointChange> deepFlipped;           // what the deep search flipped in this group (point, material before)

    bool isBorder(const std::array<int, 3>& c) const {
        return c[0] == 0 || c[1] == 0 || c[2] == 0 || c[0] == nx - 1 || c[1] == ny - 1 || c[2] == nz - 1;
    }
    void apply(const std::vector<PointChange>& ch) {
        for (const auto& [p, to] : ch) work.material[p] = to;
    }
    // Whether every block among `blocks` (lowest corners) is manifold in `work`.
    bool manifoldAt(const std::vector<std::size_t>& blocks) const;
    // Whether block b (lowest corner) is not manifold in `work`.
    bool badBlock(std::size_t b) const;
    // Whether a changed point of another group lies within 1 of (x, y, z)
    // (not on the grid's border).
    bool nextToOtherGroup(int x, int y, int z, std::int32_t group);
    // The points within 1 of `points`, sorted.
    std::vector<std::size_t> around(const std::vector<std::size_t>& points) const;
    Extent extentOf(const std::vector<std::size_t>& points) const;
    // The repair's change of `points`.
    std::vector<PointChange> changeOf(const std::vector<std::size_t>& points) const;
    // The points with their materials in `work` now.
    std::vector<PointChange> snapshot(const std::vector<std::size_t>& points) const;
    // The points of `before` whose material differs now: the change since.
    std::vector<PointChange> changedSince(const std::vector<PointChange>& before) const;
    // Whether the change since `before` keeps every material's polygon
    // surface, checked exactly from that state (work is left as it was).
    bool keepsSince(const std::vector<PointChange>& before);
    // How far the change since `before` is from the sampled labels: the
    // points it leaves off them, and |field| there (the tie-break of every search).
    void offSampled(const std::vector<PointChange>& before, std::size_t& diff, double& cost) const;
    // Lists `points` in the report as a place no search could mend.
    void reportUnmended(const std::vector<std::size_t>& points, long long eulerChange);
};

// The flip search: up to maxDepth flips of points in `near` on top of the
// target's change that leave every block around them manifold and make the
// whole change keep the polygon surface; applies the best one, false if none.
bool flipSearch(MatchState& s, const Target& t, const std::vector<std::size_t>& near, int maxDepth);

// The deep search, for what the flip search cannot mend: a beam search over
// sets of options, then annealing; applies the set it finds (recorded in
// s.deepFlipped), false if none.
bool deepSearch(MatchState& s, const Target& t);

}  // namespace isohex::octree

// matchPolygonTopology's flip search: the repair's change of a place plus 1,
// 2 or 3 flips of points around it, every combination in a fixed order.
#include <algorithm>
#include <vector>

#include "GridBlocks.hpp"
#include "TopologyMatchState.hpp"

namespace isohex::octree {

namespace {

// At most this many trials per search (a bound on the time a noisy place can
// take: three flips among 80 options are 82,160 trials).
constexpr std::size_t kMatchTrials = 150'000;
// Three flips only among at most this many options (options^3 trials).
constexpr std::size_t kThreeFlipOptions = 80;

// Up to maxDepth flips of points in `near`, on top of the target's change
// (already applied), that leave every block around them manifold and make
// the whole change (from the target's `before`) keep the polygoniser's
// surface; of those with the fewest flips, the one nearest the sampled
// labels (fewest points off them, then smallest |field| there).
class FlipSearch {
public:
    FlipSearch(MatchState& s, const Target& t, const std::vector<std::size_t>& near) : s_(s), t_(t) {
        collectLater(near);
        collectOptions(near);
    }

    // Tries 1, 2, ... maxDepth flips until some depth finds a set; applies
    // the best one. False if none.
    bool run(int maxDepth);

private:
    void collectLater(const std::vector<std::size_t>& near);
    void collectOptions(const std::vector<std::size_t>& near);
    void choose(int depth, int level, int from);
    void evaluate();
    bool keepsCubeEuler();

    MatchState& s_;
    const Target& t_;
    // of the later points, those a block around a flip can hold (within 1
    // of `near`): set and reset on every trial
    std::vector<PointChange> laterHere_, laterHereBefore_;
    std::vector<PointChange> options_;  // (point, material it may take)
    bool found_ = false;
    std::vector<PointChange> best_;
    std::size_t bestDiff_ = 0;
    double bestCost_ = 0;
    std::vector<int> pick_;
    std::vector<PointChange> flips_, undo_;  // reused by every trial
    std::vector<std::size_t> flipped_, blocks_;
    std::size_t trials_ = 0;
};

bool FlipSearch::run(int maxDepth) {
    for (int depth = 1; depth <= maxDepth && !found_; ++depth) {
        if (depth == 3 && options_.size() > kThreeFlipOptions) break;
        pick_.assign(depth, 0);
        choose(depth, 0, 0);
    }
    if (found_) s_.apply(best_);
    return found_;
}

// The later points within 1 of `near`, as the repair changes them and as they are now.
void FlipSearch::collectLater(const std::vector<std::size_t>& near) {
    if (!t_.later) return;
    const std::vector<std::size_t> reach = s_.around(near);
    for (std::size_t n = 0; n < t_.later->size(); ++n)
        if (std::binary_search(reach.begin(), reach.end(), (*t_.later)[n].first)) {
            laterHere_.push_back((*t_.later)[n]);
            laterHereBefore_.push_back((*t_.laterBefore)[n]);
        }
}

// The options: each point of `near` off the border, not frozen and not next
// to another group, may take the background, its sampled or repaired
// material, or a material of one of its 6 neighbours.
void FlipSearch::collectOptions(const std::vector<std::size_t>& near) {
    const Grid& g = s_.g;
    for (std::size_t p : near) {
        const auto c = g.coords(p);
        if (s_.isBorder(c) || (t_.frozen && t_.frozen->count(p))) continue;
        if (s_.nextToOtherGroup(c[0], c[1], c[2], t_.group)) continue;
        std::vector<std::int32_t> to{0, s_.sampled.material[p], s_.repaired.material[p]};
        for (int d = 0; d < 6; ++d) {
            const int x = c[0] + (d == 0) - (d == 1), y = c[1] + (d == 2) - (d == 3), z = c[2] + (d == 4) - (d == 5);
            to.push_back(s_.work.material[g.index(x, y, z)]);
        }
        std::sort(to.begin(), to.end());
        to.erase(std::unique(to.begin(), to.end()), to.end());
        for (std::int32_t m : to)
            if (m != s_.work.material[p]) options_.emplace_back(p, m);
    }
}

// The combinations of `depth` options at distinct points, in order, from
// option `from` on for pick_[level]; stops past kMatchTrials.
void FlipSearch::choose(int depth, int level, int from) {
    if (trials_ >= kMatchTrials) return;
    if (level == depth) {
        evaluate();
        return;
    }
    for (int q = from; q < static_cast<int>(options_.size()); ++q) {
        bool clash = false;
        for (int e = 0; e < level; ++e) clash = clash || options_[pick_[e]].first == options_[q].first;
        if (clash) continue;
        pick_[level] = q;
        choose(depth, level + 1, q + 1);
    }
}

// Whether the picked flips (applied, the later points changed) leave the
// blocks around them manifold and change the cubes' Euler characteristic by
// the opposite of the target's change: where both states are manifold the
// polygoniser's surface changes its Euler characteristic as the cubes'
// boundary does, a cheap filter before the exact test.
bool FlipSearch::keepsCubeEuler() {
    if (!s_.manifoldAt(blocks_)) return false;
    const long long chi = cubeEuler(s_.work, blocks_);
    s_.apply(undo_);
    const bool keeps = chi - cubeEuler(s_.work, blocks_) == -t_.eulerChange;
    s_.apply(flips_);
    return keeps;
}

// One trial: the picked flips, kept as the best when they pass the filter and
// the exact test and are nearer the sampled labels than the best so far.
void FlipSearch::evaluate() {
    ++trials_;
    flips_.clear();
    undo_.clear();
    flipped_.clear();
    for (int q : pick_) {
        flips_.push_back(options_[q]);
        flipped_.push_back(options_[q].first);
        undo_.emplace_back(options_[q].first, s_.work.material[options_[q].first]);
    }
    blocksAround(s_.g, flipped_, blocks_);
    s_.apply(laterHere_);
    s_.apply(flips_);
    const bool candidate = keepsCubeEuler();
    s_.apply(laterHereBefore_);
    if (candidate && s_.keepsSince(t_.before)) {
        std::size_t diff = 0;
        double cost = 0;
        s_.offSampled(t_.before, diff, cost);
        if (!found_ || diff < bestDiff_ || (diff == bestDiff_ && cost < bestCost_)) {
            found_ = true;
            best_ = flips_;
            bestDiff_ = diff;
            bestCost_ = cost;
        }
    }
    s_.apply(undo_);
}

}  // namespace

bool flipSearch(MatchState& s, const Target& t, const std::vector<std::size_t>& near, int maxDepth) {
    return FlipSearch(s, t, near).run(maxDepth);
}

}  // namespace isohex::octree

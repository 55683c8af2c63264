// matchPolygonTopology's deep search, for a place the flip search cannot
// mend: a beam search over sets of options, scored by how far the polygon
// surface around the place is from before and by the blocks left bad; when
// the beam finds none, seeded annealing chains over the same options, and a
// set they reach is shrunk while it stays exact.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "GridBlocks.hpp"
#include "PolygonWindow.hpp"
#include "TopologyMatchState.hpp"

namespace isohex::octree {

namespace {

// Options are flips of boundary points within kDeepReach of the place;
// kDeepBeam sets are kept per round, at most kDeepDepth options and
// kDeepTrials trials; a unit of topology distance weighs as much as
// kDeepTopologyWeight bad blocks; a beam stops after kDeepPatience rounds
// without a better best score.
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

// A set of options and what it scores.
struct Trial {
    std::vector<int> pick;  // option indices, ascending
    long long score = 0;
    std::size_t diff = 0;   // points off the sampled labels that were not before
    double cost = 0;        // |field| at those
};

// The beam's order: score, then nearest the sampled labels, then the options.
bool ranks(const Trial& a, const Trial& b) {
    return std::tie(a.score, a.diff, a.cost, a.pick) < std::tie(b.score, b.diff, b.cost, b.pick);
}

// Where an annealing chain is: the bad blocks, the topology distance and the
// options on.
struct Chain {
    long long bad = 0, dist = 0, picks = 0;
};

// The deep search of one place. The box is the place's points and kDeepReach
// around them (inside the grid's border). An option is one step: a flip of a
// point on a material boundary in the box, none next to another group or
// frozen; or a move that isolates a one-point piece (speck or pocket) of the
// sampled labels: the point takes its sampled material and its 26 neighbours
// that have that material take the one most of its 6 neighbours have in the
// sampled labels (no sequence of single flips reaches that without passing
// through states that score worse); or the piece moved: a point within 2 of
// it whose 26 neighbours all have one other material takes its material (a
// piece of one point there is manifold). A set is scored by how far the
// polygon surface in a window around the box is from what it was before the
// place (McProbe, per material) and by the blocks it leaves bad.
class DeepSearch {
public:
    DeepSearch(MatchState& s, const Target& t);

    // Beam, then annealing; applies the set found. False if none.
    bool run();

private:
    void snapshotBox();
    void collectOptions();
    void optionsAt(int x, int y, int z);
    void isolatePiece(int x, int y, int z, std::int32_t m, std::int32_t around);
    void movePiece(int x, int y, int z, std::int32_t m);
    bool allowed(int x, int y, int z);
    void makeProbes();
    void collectLater();
    void countBaseBad();
    long long distance();
    bool evaluate(Trial& t, bool& goal, long long threshold);
    std::optional<Trial> beamSearch();
    void extendBeam(const std::vector<Trial>& beam, std::set<std::vector<int>>& seen, std::vector<Trial>& next,
                    std::vector<Trial>& goals);
    std::optional<Trial> anneal();
    bool runChain(int chain, Trial& t);
    bool annealStep(std::mt19937& rng, long step, Chain& c, Trial& t);
    bool reachesGoal(Trial& t);
    long long badIn(const std::vector<std::size_t>& blocks);
    void toggle(int q);
    void shrink(Trial& t);
    bool dropped(Trial& t, std::size_t n, std::size_t n2);
    bool take(const Trial& won);

    MatchState& s_;
    const Target& t_;
    std::array<int, 3> lo_{}, hi_{};  // the box
    // the box and 1 around it (the points its blocks hold), as they are now
    // (the place changed) and were before the place
    std::vector<PointChange> after_, before_;
    std::vector<std::vector<PointChange>> options_;
    std::vector<std::unique_ptr<McProbe>> probes_;
    // Later parts of a wide group in the box, changed as the repair changes
    // them when blocks are judged, and left as they are for the surface.
    std::vector<PointChange> laterHere_, laterHereBefore_;
    // Bad blocks are counted as the options change them: the blocks around
    // any option bad now, plus the change in the blocks around a set's options.
    std::unordered_set<std::size_t> baseBad_;
    std::vector<std::size_t> flipped_, blocks_;  // scratch of evaluate
    std::vector<PointChange> undo_;
    std::size_t trials_ = 0;
    // the annealing's state: the materials an option on replaced (empty:
    // off), the option holding a point, the blocks around an option (when
    // first drawn)
    std::vector<std::vector<std::int32_t>> onWas_;
    std::unordered_map<std::size_t, int> takenBy_;
    std::vector<std::vector<std::size_t>> blocksOf_;
};

DeepSearch::DeepSearch(MatchState& s, const Target& t) : s_(s), t_(t) {
    const Extent box = s_.extentOf(t_.points);
    for (int a = 0; a < 3; ++a) {
        lo_[a] = std::max(box.lo[a] - kDeepReach, 1);
        hi_[a] = std::min(box.hi[a] + kDeepReach, s_.g.dims[a] - 2);
    }
    snapshotBox();
    collectOptions();
    makeProbes();
    collectLater();
    countBaseBad();
}

// The search: the beam; when it finds nothing, the annealing, whose set is
// shrunk before it is applied.
bool DeepSearch::run() {
    if (std::optional<Trial> won = beamSearch()) return take(*won);
    if (std::optional<Trial> reached = anneal()) {
        shrink(*reached);
        return take(*reached);
    }
    s_.rep.deepTrials += trials_;
    return false;
}

// after_ and before_: the box and 1 around it now, and with the place's
// points back at their sampled materials.
void DeepSearch::snapshotBox() {
    const Grid& g = s_.g;
    for (int z = lo_[2] - 1; z <= hi_[2] + 1; ++z)
        for (int y = lo_[1] - 1; y <= hi_[1] + 1; ++y)
            for (int x = lo_[0] - 1; x <= hi_[0] + 1; ++x) {
                const std::size_t p = g.index(x, y, z);
                after_.emplace_back(p, s_.work.material[p]);
            }
    before_ = after_;
    const std::unordered_set<std::size_t> inGroup(t_.points.begin(), t_.points.end());
    for (auto& [p, m] : before_)
        if (inGroup.count(p)) m = s_.sampled.material[p];
}

// Whether a point may change: in the box, not frozen, not next to another group.
bool DeepSearch::allowed(int x, int y, int z) {
    if (x < lo_[0] || y < lo_[1] || z < lo_[2] || x > hi_[0] || y > hi_[1] || z > hi_[2]) return false;
    return !(t_.frozen && t_.frozen->count(s_.g.index(x, y, z))) && !s_.nextToOtherGroup(x, y, z, t_.group);
}

// The options at every allowed point of the box, sorted, unique (a point can
// be offered twice, from two pieces: one is kept).
void DeepSearch::collectOptions() {
    for (int z = lo_[2]; z <= hi_[2]; ++z)
        for (int y = lo_[1]; y <= hi_[1]; ++y)
            for (int x = lo_[0]; x <= hi_[0]; ++x)
                if (allowed(x, y, z)) optionsAt(x, y, z);
    std::sort(options_.begin(), options_.end());
    options_.erase(std::unique(options_.begin(), options_.end()), options_.end());
}

// The options of one point: its flips when it is on a material boundary
// (to the background, its sampled or repaired material or a 6-neighbour's);
// and, when it is a one-point piece of the sampled labels, the piece
// isolated or moved.
void DeepSearch::optionsAt(int x, int y, int z) {
    const Grid& g = s_.g;
    const Labels& work = s_.work;
    const std::size_t p = g.index(x, y, z);
    bool boundary = false;
    std::vector<std::int32_t> to{0, s_.sampled.material[p], s_.repaired.material[p]};
    std::map<std::int32_t, int> sampled6;  // the sampled materials of the 6 neighbours
    for (int q = 0; q < 27; ++q) {
        const std::size_t o = g.index(x + q % 3 - 1, y + q / 3 % 3 - 1, z + q / 9 - 1);
        boundary = boundary || work.material[o] != work.material[p];
        if (q == 4 || q == 10 || q == 12 || q == 14 || q == 16 || q == 22) {
            to.push_back(work.material[o]);
            ++sampled6[s_.sampled.material[o]];
        }
    }
    if (boundary) {
        std::sort(to.begin(), to.end());
        to.erase(std::unique(to.begin(), to.end()), to.end());
        for (std::int32_t m : to)
            if (m != work.material[p]) options_.push_back({PointChange{p, m}});
    }
    const std::int32_t m = s_.sampled.material[p];
    if (sampled6.count(m)) return;  // not a one-point piece
    std::int32_t around = 0;
    int most = -1;
    for (const auto& [mat, n] : sampled6)
        if (n > most) {
            most = n;
            around = mat;
        }
    isolatePiece(x, y, z, m, around);
    movePiece(x, y, z, m);
}

// The one-point piece of material m at (x, y, z) set apart: the point takes
// m, its 26 neighbours that have m take `around`.
void DeepSearch::isolatePiece(int x, int y, int z, std::int32_t m, std::int32_t around) {
    const Grid& g = s_.g;
    const std::size_t p = g.index(x, y, z);
    std::vector<PointChange> move;
    if (s_.work.material[p] != m) move.emplace_back(p, m);
    bool ok = true;
    for (int q = 0; q < 27 && ok; ++q) {
        const int a = x + q % 3 - 1, b = y + q / 3 % 3 - 1, c = z + q / 9 - 1;
        const std::size_t o = g.index(a, b, c);
        if (q == 13 || s_.work.material[o] != m) continue;
        ok = allowed(a, b, c);
        move.emplace_back(o, around);
    }
    if (ok && move.size() > 1) options_.push_back(std::move(move));
}

// The one-point piece of material m at (x, y, z) moved: a point within 2
// whose 26 neighbours all have one other material takes m.
void DeepSearch::movePiece(int x, int y, int z, std::int32_t m) {
    const Grid& g = s_.g;
    const Labels& work = s_.work;
    for (int q = 0; q < 125; ++q) {
        const int a = x + q % 5 - 2, b = y + q / 5 % 5 - 2, c = z + q / 25 - 2;
        if (!allowed(a, b, c) || work.material[g.index(a, b, c)] == m) continue;
        bool interior = true;
        const std::int32_t here = work.material[g.index(a, b, c)];
        for (int r = 0; r < 27 && interior; ++r)
            interior = work.material[g.index(a + r % 3 - 1, b + r / 3 % 3 - 1, c + r / 9 - 1)] == here;
        if (interior) options_.push_back({PointChange{g.index(a, b, c), m}});
    }
}

// One probe per material the place's change or an option gives or takes a
// point, made on the state before the place.
void DeepSearch::makeProbes() {
    std::vector<std::int32_t> mats;
    for (std::size_t p : t_.points) mats.insert(mats.end(), {s_.sampled.material[p], s_.repaired.material[p]});
    for (const auto& o : options_)
        for (const auto& [p, to] : o) mats.insert(mats.end(), {s_.work.material[p], to});
    std::sort(mats.begin(), mats.end());
    mats.erase(std::unique(mats.begin(), mats.end()), mats.end());
    s_.apply(before_);
    for (std::int32_t m : mats)
        if (m != 0) probes_.push_back(std::make_unique<McProbe>(s_.work, lo_, hi_, m, s_.table));
    s_.apply(after_);
}

// The later points within 1 of the box.
void DeepSearch::collectLater() {
    if (!t_.later) return;
    for (std::size_t n = 0; n < t_.later->size(); ++n) {
        const auto c = s_.g.coords((*t_.later)[n].first);
        bool in = true;
        for (int a = 0; a < 3; ++a) in = in && c[a] >= lo_[a] - 1 && c[a] <= hi_[a] + 1;
        if (!in) continue;
        laterHere_.push_back((*t_.later)[n]);
        laterHereBefore_.push_back((*t_.laterBefore)[n]);
    }
}

// The blocks around the place's points and the options' that are bad now
// (the later points changed).
void DeepSearch::countBaseBad() {
    std::vector<std::size_t> optionPoints(t_.points);
    for (const auto& o : options_)
        for (const auto& pc : o) optionPoints.push_back(pc.first);
    s_.apply(laterHere_);
    for (std::size_t b : blocksAround(s_.g, optionPoints))
        if (s_.badBlock(b)) baseBad_.insert(b);
    s_.apply(laterHereBefore_);
}

// The topology distance of the state now, summed over the probes.
long long DeepSearch::distance() {
    long long d = 0;
    for (auto& pr : probes_) d += pr->distance();
    return d;
}

// Bad blocks among `blocks` now, the later points changed.
long long DeepSearch::badIn(const std::vector<std::size_t>& blocks) {
    long long n = 0;
    s_.apply(laterHere_);
    for (std::size_t b : blocks) n += s_.badBlock(b);
    s_.apply(laterHereBefore_);
    return n;
}

// Scores t; false (not probed) when it has more bad blocks than `threshold`
// (its score is at least that). goal: manifold and the surface kept exactly.
bool DeepSearch::evaluate(Trial& t, bool& goal, long long threshold) {
    goal = false;
    flipped_.clear();
    undo_.clear();
    for (int q : t.pick)
        for (const auto& [p, to] : options_[q]) {
            flipped_.push_back(p);
            undo_.emplace_back(p, s_.work.material[p]);
            s_.work.material[p] = to;
        }
    blocksAround(s_.g, flipped_, blocks_);
    long long bad = static_cast<long long>(baseBad_.size());
    s_.apply(laterHere_);
    for (std::size_t b : blocks_)
        bad += static_cast<long long>(s_.badBlock(b)) - static_cast<long long>(baseBad_.count(b));
    s_.apply(laterHereBefore_);
    if (bad > threshold) {
        s_.apply(undo_);
        return false;
    }
    ++trials_;
    const long long dist = distance();
    t.score = dist * kDeepTopologyWeight + bad;
    s_.offSampled(before_, t.diff, t.cost);
    if (dist == 0 && bad == 0) goal = s_.keepsSince(before_);
    s_.apply(undo_);
    return true;
}

// The beam: each round extends the kDeepBeam best sets by one option; the
// first round with a goal ends it, the goal nearest the sampled labels
// winning. Stops after kDeepPatience rounds without a better best score,
// past kDeepDepth options or kDeepTrials probed sets.
std::optional<Trial> DeepSearch::beamSearch() {
    std::vector<Trial> beam(1);
    std::set<std::vector<int>> seen;
    long long bestSoFar = std::numeric_limits<long long>::max();
    int lastGain = 0;
    for (int depth = 1; depth <= kDeepDepth && trials_ < kDeepTrials; ++depth) {
        std::vector<Trial> next, goals;
        extendBeam(beam, seen, next, goals);
        if (!goals.empty())
            return *std::min_element(goals.begin(), goals.end(), [](const Trial& a, const Trial& b) {
                return std::tie(a.diff, a.cost, a.pick) < std::tie(b.diff, b.cost, b.pick);
            });
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
    return std::nullopt;
}

// One round of the beam: every set of the beam with one more option that
// clashes with none of its own and was not seen before; a set with more bad
// blocks than the kDeepBeam best scores of the round so far is not probed.
void DeepSearch::extendBeam(const std::vector<Trial>& beam, std::set<std::vector<int>>& seen,
                            std::vector<Trial>& next, std::vector<Trial>& goals) {
    std::multiset<long long> top;  // the kDeepBeam best scores of this round so far
    for (const Trial& from : beam)
        for (int q = 0; q < static_cast<int>(options_.size()) && trials_ < kDeepTrials; ++q) {
            bool clash = false;
            for (int e : from.pick)
                for (const auto& a : options_[e])
                    for (const auto& b : options_[q]) clash = clash || a.first == b.first;
            if (clash) continue;
            Trial t;
            t.pick = from.pick;
            t.pick.insert(std::upper_bound(t.pick.begin(), t.pick.end(), q), q);
            if (!seen.insert(t.pick).second) continue;
            bool goal = false;
            const long long threshold = top.size() < kDeepBeam ? std::numeric_limits<long long>::max() : *top.rbegin();
            if (!evaluate(t, goal, threshold)) continue;
            if (goal) {
                goals.push_back(std::move(t));
                continue;
            }
            top.insert(t.score);
            if (top.size() > kDeepBeam) top.erase(std::prev(top.end()));
            next.push_back(std::move(t));
        }
}

// Annealing, when the beam found nothing: chains of random single toggles of
// options (on or off), accepted by the Metropolis rule on score +
// kAnnealOptionCost per option on, at a temperature falling from kAnnealT0 to
// kAnnealT1. The first chain that reaches a goal (checked exactly) gives its
// set. Chains are seeded by their number; the run's budget is spent in grid
// order, so the result depends on the input only (not on the thread count).
std::optional<Trial> DeepSearch::anneal() {
    onWas_.assign(options_.size(), {});
    blocksOf_.assign(options_.size(), {});
    for (int chain = 0; chain < kAnnealChains && !options_.empty() && s_.rep.annealSteps < kAnnealBudget; ++chain) {
        Trial t;
        if (runChain(chain, t)) return t;
        for (int o = static_cast<int>(options_.size()) - 1; o >= 0; --o)
            if (!onWas_[o].empty()) toggle(o);
    }
    return std::nullopt;
}

// One chain from no option on; true, with the goal in t (every option off
// again), when it reaches one.
bool DeepSearch::runChain(int chain, Trial& t) {
    std::mt19937 rng(static_cast<std::uint32_t>(chain + 1));
    Chain c;
    c.bad = static_cast<long long>(baseBad_.size());
    c.dist = distance();
    for (long step = 0; step < kAnnealSteps && s_.rep.annealSteps < kAnnealBudget; ++step)
        if (annealStep(rng, step, c, t)) return true;
    return false;
}

// One step: a random option toggled (a step that would switch on an option
// with a point already taken does nothing), kept or undone by the Metropolis
// rule; true when the state reached is a goal.
bool DeepSearch::annealStep(std::mt19937& rng, long step, Chain& c, Trial& t) {
    ++s_.rep.annealSteps;
    const double T = kAnnealT0 * std::pow(kAnnealT1 / kAnnealT0, static_cast<double>(step) / static_cast<double>(kAnnealSteps));
    const int q = static_cast<int>(rng() % options_.size());
    const bool wasOn = !onWas_[q].empty();
    bool clash = false;
    for (const auto& pc : options_[q]) clash = clash || (!wasOn && takenBy_.count(pc.first) > 0);
    if (clash) return false;
    if (blocksOf_[q].empty()) {
        std::vector<std::size_t> pts;
        for (const auto& pc : options_[q]) pts.push_back(pc.first);
        blocksAround(s_.g, pts, blocksOf_[q]);
    }
    const long long b0 = badIn(blocksOf_[q]);
    toggle(q);
    const long long b1 = badIn(blocksOf_[q]);
    const long long d = distance();
    const long long newBad = c.bad - b0 + b1, newPicks = c.picks + (wasOn ? -1 : 1);
    if (d == 0 && newBad == 0) {
        // a set the probes pass but the exact test does not is kept and the
        // chain goes on from it
        if (reachesGoal(t)) return true;
        c = Chain{newBad, d, newPicks};
        return false;
    }
    const double dE = static_cast<double>((d - c.dist) * kDeepTopologyWeight + (newBad - c.bad)) +
                      kAnnealOptionCost * static_cast<double>(newPicks - c.picks);
    const std::uint32_t r = rng();
    if (dE <= 0 || static_cast<double>(r) < std::exp(-dE / T) * 4294967296.0) c = Chain{newBad, d, newPicks};
    else toggle(q);
    return false;
}

// Whether the options on now are a goal, checked exactly from the state
// before the place; if so t holds them and they are switched off.
bool DeepSearch::reachesGoal(Trial& t) {
    t.pick.clear();
    for (int o = 0; o < static_cast<int>(options_.size()); ++o)
        if (!onWas_[o].empty()) t.pick.push_back(o);
    for (int o : t.pick) toggle(o);
    bool goal = false;
    evaluate(t, goal, std::numeric_limits<long long>::max());
    if (goal) return true;
    for (int o : t.pick) toggle(o);
    return false;
}

// Switches option q off if it is on, else on (only when no point of it is taken).
void DeepSearch::toggle(int q) {
    if (!onWas_[q].empty()) {
        for (std::size_t n = 0; n < options_[q].size(); ++n) {
            s_.work.material[options_[q][n].first] = onWas_[q][n];
            takenBy_.erase(options_[q][n].first);
        }
        onWas_[q].clear();
        return;
    }
    for (const auto& [p, to] : options_[q]) {
        onWas_[q].push_back(s_.work.material[p]);
        takenBy_.emplace(p, q);
        s_.work.material[p] = to;
    }
}

// Shrinks a goal the annealing reached: drops its options one at a time,
// then two at a time, while it stays a goal, until none can be dropped.
void DeepSearch::shrink(Trial& t) {
    for (bool shrunk = true; shrunk;) {
        shrunk = false;
        for (std::size_t n = 0; n < t.pick.size();)
            if (dropped(t, n, t.pick.size())) shrunk = true;
            else ++n;
        for (std::size_t n = 0; n < t.pick.size() && !shrunk; ++n)
            for (std::size_t n2 = n + 1; n2 < t.pick.size() && !shrunk; ++n2) shrunk = dropped(t, n, n2);
    }
}

// t without options n (and n2 > n, if given); true, and t that set, when it
// is still a goal.
bool DeepSearch::dropped(Trial& t, std::size_t n, std::size_t n2) {
    Trial u;
    u.pick = t.pick;
    if (n2 < u.pick.size()) u.pick.erase(u.pick.begin() + static_cast<std::ptrdiff_t>(n2));
    u.pick.erase(u.pick.begin() + static_cast<std::ptrdiff_t>(n));
    bool still = false;
    evaluate(u, still, 0);
    if (still) t = std::move(u);
    return still;
}

// Applies a winning set, recorded in deepFlipped (for the wide-group fallback).
bool DeepSearch::take(const Trial& won) {
    for (int q : won.pick)
        for (const auto& [p, to] : options_[q]) {
            s_.deepFlipped.emplace_back(p, s_.work.material[p]);
            s_.work.material[p] = to;
        }
    s_.rep.deepTrials += trials_;
    return true;
}

}  // namespace

bool deepSearch(MatchState& s, const Target& t) { return DeepSearch(s, t).run(); }

}  // namespace isohex::octree

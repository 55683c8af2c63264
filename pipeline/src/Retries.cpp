#include "isohex/pipeline/Retries.hpp"

#include <memory>
#include <utility>

#include "Format.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/GridEdits.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/Regions.hpp"
#include "isohex/octree/RepairedDomain.hpp"
#include "isohex/pipeline/Contour.hpp"
#include "isohex/pipeline/GridPositions.hpp"
#include "isohex/pipeline/LocalRetry.hpp"

namespace isohex::pipeline {

namespace {

// What the attempts share.
struct RetryState {
    Meshing& best;
    const MeshSettings& settings;
    StageSink& sink;
    RetryResult result;
    octree::Grid grid;                               // the element grid (edits keep it)
    std::vector<std::size_t> frozen;                 // grid points edited once, never again
    std::shared_ptr<const octree::Labels> sampled;   // the grid sampled afresh, made on first use
    bool local = false;                              // retries optimise a neighbourhood (LocalRetry.hpp)
};

// The hexes an attempt works on: inverted ones first (while any is left the
// edits go to them alone), else the worst kMaxStuckToRetry flat ones. Empty
// with `why` set when there are too many inverted ones to be a few stuck places.
std::vector<Index> hexesToWorkOn(const Stuck& stuck, std::optional<std::string>& why) {
    std::vector<Index> work = stuck.inverted.empty() ? stuck.flat : stuck.inverted;
    if (!stuck.inverted.empty() && work.size() > kMaxStuckToRetry) {
        why = "more than " + std::to_string(kMaxStuckToRetry) + " inverted hexes: not a few stuck places";
        return {};
    }
    if (work.size() > kMaxStuckToRetry) work.resize(kMaxStuckToRetry);
    return work;
}

// A part's grid edits stay kPartGhostLayers clear of its cuts, where the
// neighbour part, which does not see them, meshes the same nodes (what an
// edit changes can spread as far as what a cut node depends on).
void dropHexesNearCuts(const RetryState& s, std::vector<std::array<double, 3>>& at, std::vector<Index>& work) {
    const auto& part = s.best.prepared.part;
    if (!part) return;
    const double margin = kPartGhostLayers;
    std::size_t kept = 0;
    for (std::size_t i = 0; i < work.size(); ++i) {
        const double layer = at[i][static_cast<std::size_t>(part->axis)] + part->first;
        if ((part->cutBelow() && layer < part->coreLo + margin) || (part->cutAbove() && layer > part->coreHi - margin))
            continue;
        at[kept] = at[i];
        work[kept++] = work[i];
    }
    at.resize(kept);
    work.resize(kept);
}

// What the retries work on and the warnings name: with a floor, the
// inverted and the flat hexes; without one, the inverted hexes alone (no
// pass over the scaled Jacobians).
Stuck leftStuck(const HexMesh& mesh, double floor) {
    if (floor > 0) return stuckHexes(mesh, floor);
    Stuck s;
    s.inverted = invertedHexes(mesh);
    return s;
}

std::string scopeText(int cells) {
    return cells == kWholeVolume ? "the whole volume" : std::to_string(cells) + " cells around the edits";
}

// Meshes the edited labels `q` again on the field repaired for them; returns
// how many grid points that field changes. Local retries contour and pillow
// the whole grid but optimise only within `cells` grid cells of the edits
// (`tried` then receives its region).
std::size_t meshEdited(RetryState& s, Prepared& q, const std::vector<octree::PointEdit>& edits, int cells,
                       Meshing& again, RetryAttempt& tried) {
    const Prepared& p = s.best.prepared;
    if (!s.sampled) s.sampled = std::make_shared<const octree::Labels>(octree::sampleLabels(*p.domain, s.grid));
    auto repaired = std::make_shared<octree::RepairedDomain>(*p.domain, *s.sampled, q.labels);
    const std::size_t repairedPoints = repaired->changedPoints();
    q.repairedDomain = std::move(repaired);
    if (!s.local || cells == kWholeVolume) {
        again = meshLabels(std::move(q), s.settings, s.sink);
        return repairedPoints;
    }
    std::vector<std::size_t> edited;
    for (const auto& e : edits) edited.push_back(e.point);
    LocalRegion region;
    again = meshLabelsNear(std::move(q), s.settings, s.sink, s.best, edited, cells, region);
    tried.region = regionRecord(region);
    return repairedPoints;
}

// One attempt: edit grid points next to the stuck hexes, mesh again, keep
// the result if better. False when the attempt could not mesh (the loop stops).
bool attempt(RetryState& s, int n, int maxRetries, double floor) {
    RetryAttempt tried;
    tried.attempt = n;
    tried.before = s.result.stuck.counts();
    const Stuck& stuck = s.result.stuck;
    std::vector<Index> work = hexesToWorkOn(stuck, tried.notMeshedBecause);
    if (tried.notMeshedBecause) {
        s.result.attempts.push_back(tried);
        return false;
    }
    std::vector<std::array<double, 3>> at = hexCentresInGrid(s.best.mesh, s.grid, work);
    dropHexesNearCuts(s, at, work);
    Prepared q = s.best.prepared;
    const std::vector<octree::PointEdit> edits = octree::editNearInvertedHexes(q.labels, at, s.frozen);
    for (const auto& e : edits) {
        const auto [i, j, k] = s.grid.coords(e.point);
        tried.edits.push_back({{i, j, k}, s.grid.point(i, j, k), e.from, e.to});
        s.frozen.push_back(e.point);
    }
    if (edits.empty()) {
        tried.notMeshedBecause = "no grid point next to these hexes can change material without changing a topology";
        s.result.attempts.push_back(tried);
        return false;
    }
    // the stages' progress starts over: say why
    s.sink.note("info", "meshing again (retry " + std::to_string(n) + " of " + std::to_string(maxRetries) + "): " +
                            std::to_string(edits.size()) + " grid point(s) next to " + std::to_string(work.size()) +
                            (stuck.inverted.empty() ? " nearly flat" : " inverted") + " hex(es) change material");
    // The near neighbourhood, then the wide one, then (the last resort) the
    // whole volume, until one helps: where kept nodes meet new ones a
    // neighbourhood can leave a hex flat, or the inverted hexes it was for.
    const std::vector<int> scopes = remeshScopes(s.local);
    Meshing again;
    std::size_t repairedPoints = 0;
    Stuck now;
    bool better = false;
    for (std::size_t i = 0; i < scopes.size(); ++i) {
        if (i > 0)
            s.sink.note("info", "retry " + std::to_string(n) + ": optimising " + scopeText(scopes[i - 1]) +
                                    " did not help; optimising " + scopeText(scopes[i]));
        Prepared edited = q;
        tried.region.reset();
        repairedPoints = meshEdited(s, edited, edits, scopes[i], again, tried);
        now = stuckHexes(again.mesh, floor);
        better = now.betterThan(stuck, floor);
        if (better && (stuck.inverted.empty() || now.inverted.size() < stuck.inverted.size())) break;
    }
    ++s.result.meshedAgain;
    tried.after = now.counts();
    tried.kept = better;
    s.result.attempts.push_back(tried);
    if (better) {
        // (the report's "extracted" of a mesh kept here counts the finished mesh, as it always has)
        again.contouredHexes = again.mesh.hexCount();
        again.contouredNodes = again.mesh.nodeCount();
        again.prepared.facts.grid.repairedFieldPoints = repairedPoints;
        s.best = std::move(again);
        s.result.stuck = std::move(now);
        s.result.pointsEdited += edits.size();
    }
    return true;
}

}  // namespace

Meshing meshLabels(Prepared prepared, const MeshSettings& settings, StageSink& sink) {
    Meshing m;
    m.prepared = std::move(prepared);
    if (settings.adaptive) m.adaptive.emplace();
    HeldBack heldBack;
    m.mesh = contour(m.prepared, settings, sink, m.adaptive ? &*m.adaptive : nullptr, &heldBack);
    m.contouredHexes = m.mesh.hexCount();
    m.contouredNodes = m.mesh.nodeCount();
    if (!m.prepared.part) {
        const bool keyed = keepsNodeKeys(m, settings);
        if (keyed) m.nodeKeys = storedContouredKeys(m.mesh, m.prepared);
        std::vector<isohex::PillowResult> passes;
        m.pillow = pillowBoundary(m.mesh, settings, sink, keyed ? &passes : nullptr, &heldBack);
        if (keyed) addSheetKeys(m.nodeKeys, passes, m.mesh, settings);
        // the sheet's hexes are appended, each on a boundary hex of the finest level
        if (m.adaptive) m.adaptive->hexLevel.resize(m.mesh.hexCount(), 0);
        m.optimization = optimize(m.mesh, m.prepared, settings, sink, false);
        return m;
    }
    // A part: keys from the contoured cells and the sheets, then only the
    // part's own hexes are optimised, with the nodes on its cuts frozen (they
    // stay frozen through the retries and the relaxation: runMeshPipeline
    // gives them their classes back).
    std::vector<NodeKey> keys = contourKeys(m.mesh, *m.prepared.part);
    const std::vector<std::int32_t> materials = sortedMaterials(m.mesh);
    std::vector<isohex::PillowResult> passes;
    m.pillow = pillowBoundary(m.mesh, settings, sink, &passes, &heldBack);
    addCopyKeys(keys, passes, materials);
    m.partNodes = keepOwnHexes(m.mesh, std::move(keys), *m.prepared.part);
    m.optimization = optimize(m.mesh, m.prepared, settings, sink, false);
    return m;
}

RetryResult retryStuckHexes(Meshing& best, const MeshSettings& settings, StageSink& sink) {
    const Stopwatch clock;
    const bool dual = settings.method == Method::Dual;
    const int maxRetries = dual ? settings.retries.value_or(kDefaultRetries) : 0;
    const double floor = dual ? settings.retryBelow.value_or(kDefaultRetryBelow) : 0.0;
    // the uniform mesh --adaptive kept (AdaptiveContour.hpp, keepTree) is
    // retried as the uniform mesher retries it, its adaptive facts kept
    MeshSettings asUniform = settings;
    asUniform.adaptive = false;
    std::optional<AdaptiveFacts> keptFacts;
    if (best.adaptive && best.adaptive->uniformKept) keptFacts = best.adaptive;
    const MeshSettings& used = keptFacts ? asUniform : settings;
    RetryState s{best, used, sink, {}, best.prepared.labels.grid, {}, {}, localRetryApplies(best, used)};
    s.result.allowed = maxRetries;
    s.result.floor = floor;
    s.result.stuck = leftStuck(best.mesh, floor);
    for (int n = 1; n <= maxRetries && !(s.result.stuck.inverted.empty() && s.result.stuck.flat.empty()); ++n)
        if (!attempt(s, n, maxRetries, floor)) break;
    if (s.result.pointsEdited > 0) {
        // the topology of the labels meshed (the edits are simple, so it
        // is the one before; counted again rather than assumed)
        best.prepared.facts.grid.topology = octree::regionTopology(best.prepared.labels);
        sink.note("info", "changed the material of " + std::to_string(s.result.pointsEdited) +
                              " grid point(s) where hexes stayed inverted or below scaled Jacobian " +
                              shortNumber(floor) + " and meshed again (topology kept; retries in the report)");
    }
    if (keptFacts && !best.adaptive) {
        best.adaptive = std::move(keptFacts);
        best.adaptive->hexLevel.assign(best.mesh.hexCount(), 0);
    }
    s.result.seconds = clock.seconds();
    return std::move(s.result);
}

void warnStuckHexes(const Meshing& best, const RetryResult& retries, const MeshSettings& settings, StageSink& sink,
                    std::vector<std::string>& warnings) {
    const Stuck now = leftStuck(best.mesh, retries.floor);
    const std::string more = retries.meshedAgain == 0 ? ""
                                                      : " (after meshing again " + std::to_string(retries.meshedAgain) +
                                                            " time(s) with grid edits)";
    const std::string left = warnInverted(sink, best.mesh, now.inverted,
                                          best.optimization.smoothingResult.untangleFailures.size(), more,
                                          settings.fixBoundary);
    if (!left.empty()) warnings.push_back(left);
    const std::string flat = warnFlat(sink, best.mesh, now, retries.floor, retries.meshedAgain, retries.allowed);
    if (!flat.empty()) warnings.push_back(flat);
}

}  // namespace isohex::pipeline

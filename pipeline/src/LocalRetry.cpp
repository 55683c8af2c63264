#include "isohex/pipeline/LocalRetry.hpp"

#include <algorithm>
#include <string>
#include <string_view>
#include <utility>

#include "isohex/core/Error.hpp"
#include "isohex/core/Pillow.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/Submesh.hpp"
#include "isohex/pipeline/Contour.hpp"
#include "isohex/pipeline/MinQuality.hpp"
#include "isohex/pipeline/Pillow.hpp"

namespace isohex::pipeline {

namespace {

// Grid cells within `r` cells of an edited point, sorted.
std::vector<std::int64_t> cellsNear(const octree::Grid& grid, const std::vector<std::size_t>& edited, int r) {
    std::vector<std::int64_t> near;
    for (std::size_t p : edited) {
        const auto [i, j, k] = grid.coords(p);
        for (int c = k - r; c <= k + r; ++c)
            for (int b = j - r; b <= j + r; ++b)
                for (int a = i - r; a <= i + r; ++a)
                    if (grid.contains(a, b, c)) near.push_back(static_cast<std::int64_t>(grid.index(a, b, c)));
    }
    std::sort(near.begin(), near.end());
    near.erase(std::unique(near.begin(), near.end()), near.end());
    return near;
}

PartWindow wholeWindow(const octree::Grid& grid) {
    PartWindow w;
    w.whole = grid;
    w.grid = grid;
    return w;
}

// Starts `mesh` (node keys `keys`) from the optimised `kept` mesh and marks
// the nodes free to move (see the header). A node the kept mesh has too,
// away from the edits, also takes the kept node's class: the labels there
// are unchanged, so a different class is the kept run's own doing (the
// optimiser makes a curve node a surface node where its curve runs through a
// quad with two more of its nodes), which optimising the node's few hexes
// alone would undo and leave flat. Only where the surfaces and curves are
// numbered as in the kept mesh; otherwise such a node is freed.
std::vector<std::uint8_t> startFromKept(HexMesh& mesh, const std::vector<NodeKey>& keys, const HexMesh& kept,
                                        const StoredNodeKeys& keptKeys, const std::vector<std::int64_t>& near,
                                        LocalRegion& r) {
    const bool sameNumbering = mesh.surfaces == kept.surfaces && mesh.curves == kept.curves;
    std::vector<std::uint8_t> free(mesh.nodeCount(), 0);
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v) {
        const NodeKey k = keys[v];
        const bool isNear = std::binary_search(near.begin(), near.end(), k.cell);
        const Index found = keptKeys.find(k);
        if (found == kNone) {
            free[v] = 1;
        } else {
            const auto u = static_cast<std::size_t>(found);
            mesh.nodes[v] = kept.nodes[u];
            ++r.carried;
            const bool changed = mesh.nodeClass[v] != kept.nodeClass[u];
            if (changed && !isNear && sameNumbering) mesh.nodeClass[v] = kept.nodeClass[u];
            free[v] = isNear || (changed && !sameNumbering);
        }
        r.nodes += free[v];
    }
    return free;
}

// Starts `mesh` from the optimised `kept` mesh and optimises the hexes
// around the nodes within `cells` cells of the edits (see the header).
LocalRegion optimiseNearEdits(HexMesh& mesh, const std::vector<NodeKey>& keys, const HexMesh& kept,
                              const StoredNodeKeys& keptKeys, const std::vector<std::size_t>& edited, int cells,
                              const Prepared& prepared, const MeshSettings& settings, StageSink& sink) {
    const Stopwatch clock;
    LocalRegion r;
    r.cells = cells;
    r.meshHexes = mesh.hexCount();
    const std::vector<std::int64_t> near = cellsNear(prepared.labels.grid, edited, cells);
    const std::vector<std::uint8_t> free = startFromKept(mesh, keys, kept, keptKeys, near, r);
    Submesh s = cutOut(mesh, free);
    r.hexes = s.mesh.hexCount();
    // The second max-min target is decided on a whole mesh, never on a window
    // (a window's minimum says nothing of the rest).
    MeshSettings window = settings;
    window.worstHexTarget = settings.worstHexTarget.value_or(kDefaultWorstHexTarget);
    r.optimization = optimize(s.mesh, prepared, window, sink, false, OptimizeScope::Neighbourhood);
    putBack(s, mesh);  // with the free nodes' classes: the optimiser's set-up may demote curve nodes
    r.seconds = clock.seconds();
    return r;
}

// The stages of a meshing again that keeps the rest of the mesh, named apart
// ("extract_again", "pillow_again", "optimize_again"): a progress bar weighs
// them by themselves instead of as a repeat of the first meshing, whose
// optimisation of the whole volume they do not repeat, and the report times
// them apart from the first meshing's stages.
class AgainStages final : public StageSink {
public:
    explicit AgainStages(StageSink& to) : to_(to) {}
    void begin(std::string_view stage) override { to_.begin(again(stage)); }
    void progress(double fraction) override { to_.progress(fraction); }
    void end(std::string_view stage, double seconds) override { to_.end(again(stage), seconds); }
    void note(std::string_view level, const std::string& text) override { to_.note(level, text); }
    void reading(const std::string& file) override { to_.reading(file); }

private:
    static std::string again(std::string_view stage) { return std::string(stage) + "_again"; }
    StageSink& to_;
};

// One sheet layer at most, no adaptive tree, not a part.
bool numberedByGridCells(const Prepared& prepared, const MeshSettings& settings) {
    return !prepared.part && !settings.adaptive && (!settings.pillow || settings.boundaryLayers == 1);
}

}  // namespace

bool localRetryApplies(const Meshing& best, const MeshSettings& settings) {
    return numberedByGridCells(best.prepared, settings) && best.nodeKeys.size() == best.mesh.nodeCount();
}

bool keepsNodeKeys(const Meshing& m, const MeshSettings& settings) {
    MeshSettings used = settings;
    if (m.adaptive && m.adaptive->uniformKept) used.adaptive = false;
    return used.optimize && used.method == Method::Dual && numberedByGridCells(m.prepared, used);
}

std::vector<NodeKey> contouredKeys(const HexMesh& contoured, const Prepared& prepared) {
    return contourKeys(contoured, wholeWindow(prepared.labels.grid));
}

StoredNodeKeys storedContouredKeys(const HexMesh& contoured, const Prepared& prepared) {
    return StoredNodeKeys(contouredKeys(contoured, prepared), prepared.labels.material.size());
}

void addSheetKeys(StoredNodeKeys& keys, const std::vector<isohex::PillowResult>& passes, const HexMesh& mesh,
                  const MeshSettings& settings) {
    if (settings.pillow) keys.addSheets(passes, sortedMaterials(mesh));
}

Meshing meshLabelsNear(Prepared prepared, const MeshSettings& settings, StageSink& sink, const Meshing& kept,
                       const std::vector<std::size_t>& edited, int cells, LocalRegion& region) {
    if (kept.nodeKeys.size() != kept.mesh.nodeCount())
        throw Error("meshing again: the kept mesh has no node keys (please report this with the input)");
    AgainStages stages(sink);
    Meshing m;
    m.prepared = std::move(prepared);
    HeldBack heldBack;
    m.mesh = contour(m.prepared, settings, stages, nullptr, &heldBack);
    m.contouredHexes = m.mesh.hexCount();
    m.contouredNodes = m.mesh.nodeCount();
    m.nodeKeys = storedContouredKeys(m.mesh, m.prepared);
    std::vector<isohex::PillowResult> passes;
    m.pillow = pillowBoundary(m.mesh, settings, stages, &passes, &heldBack);
    addSheetKeys(m.nodeKeys, passes, m.mesh, settings);
    region = optimiseNearEdits(m.mesh, m.nodeKeys.expand(), kept.mesh, kept.nodeKeys, edited, cells, m.prepared,
                               settings, stages);
    m.optimization = kept.optimization;
    return m;
}

std::vector<int> remeshScopes(bool local) {
    if (!local) return {kWholeVolume};
    return {kLocalRetryCells, kWideRetryCells, kWholeVolume};
}

std::vector<std::size_t> changedPoints(const octree::Labels& before, const octree::Labels& after) {
    std::vector<std::size_t> changed;
    for (std::size_t p = 0; p < after.material.size(); ++p)
        if (before.material[p] != after.material[p]) changed.push_back(p);
    return changed;
}

RetryRegion regionRecord(const LocalRegion& region) {
    const smoothing::SmoothingResult& o = region.optimization.smoothingResult;
    return RetryRegion{region.nodes,
                       region.hexes,
                       region.meshHexes,
                       region.carried,
                       region.cells,
                       o.invertedBefore,
                       static_cast<std::size_t>(o.untangleSweeps),
                       static_cast<std::size_t>(o.sweeps),
                       region.seconds};
}

}  // namespace isohex::pipeline

#include "isohex/pipeline/Compare.hpp"

#include <set>
#include <string>
#include <vector>

#include "isohex/core/Collapse.hpp"
#include "isohex/core/Dice.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SheetSelection.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/pipeline/Contour.hpp"
#include "isohex/pipeline/Pillow.hpp"
#include "isohex/pipeline/ReportJson.hpp"

namespace isohex::pipeline {

namespace {

// The connectivity of a mesh between two sheet operations. A refused
// operation leaves the mesh untouched, so the next attempt reuses it: a loop
// of attempts costs one rebuild per sheet that changed the mesh.
struct SheetEditState {
    Topology topo;
    DualSheets sheets;
    std::vector<Index> fundamental;        // only when extracting
    std::set<std::string> defects;         // only when extracting
};

// `defects`: topologicalDefects(mesh) when the caller has it (a collapse
// that just succeeded), else it is computed when extracting.
SheetEditState sheetEditState(const HexMesh& mesh, bool extracting, std::set<std::string>* defects = nullptr) {
    SheetEditState st;
    st.topo = buildTopology(mesh);
    st.sheets = buildSheets(mesh, st.topo);
    if (extracting) {
        st.fundamental = fundamentalSheets(mesh, st.topo, st.sheets);
        st.defects = defects ? std::move(*defects) : topologicalDefects(mesh);
    }
    return st;
}

// Dices randomly drawn sheets once each until the mesh has at least `target` hexes.
nlohmann::json diceUntil(HexMesh& mesh, std::size_t target, std::uint64_t seed) {
    nlohmann::json j;
    std::size_t diced = 0;
    SheetEditState st = sheetEditState(mesh, false);
    for (std::uint64_t round = 0; mesh.hexCount() < target && round < 100000; ++round) {
        const auto pick = randomSheets(st.sheets, 1, seed + round);
        if (pick.empty()) break;
        try {
            dice(mesh, st.topo, st.sheets, pick[0], 1);
            ++diced;
            st = sheetEditState(mesh, false);
        } catch (const Error&) {
            // a self-intersecting sheet: draw another
        }
    }
    j["sheets_diced"] = diced;
    return j;
}

// Extracts randomly drawn non-fundamental sheets until at most `target` hexes
// remain; sheets whose extraction is refused are skipped.
nlohmann::json extractUntil(HexMesh& mesh, std::size_t target, std::uint64_t seed) {
    nlohmann::json j;
    std::size_t extracted = 0, refused = 0;
    SheetEditState st = sheetEditState(mesh, true);
    for (std::uint64_t round = 0; mesh.hexCount() > target && round < 100000; ++round) {
        const auto pick = randomSheets(st.sheets, 1, seed + round, st.fundamental);
        if (pick.empty()) break;
        try {
            std::set<std::string> after;
            collapse(mesh, st.topo, st.sheets, pick[0], st.defects, &after);
            ++extracted;
            st = sheetEditState(mesh, true, &after);
        } catch (const Error&) {
            ++refused;
            if (refused > 50 + 10 * extracted) break;  // nothing left that can go
        }
    }
    j["sheets_extracted"] = extracted;
    j["extractions_refused"] = refused;
    return j;
}

}  // namespace

const char* variantKey(CompareVariantKind kind) {
    switch (kind) {
        case CompareVariantKind::NoSheet: return "a";
        case CompareVariantKind::Sheet: return "b";
        case CompareVariantKind::NoSheetDiced: return "c";
        case CompareVariantKind::SheetExtracted: return "d";
    }
    return "?";
}

const char* variantLabel(CompareVariantKind kind) {
    switch (kind) {
        case CompareVariantKind::NoSheet: return "no sheet";
        case CompareVariantKind::Sheet: return "fundamental sheet";
        case CompareVariantKind::NoSheetDiced: return "no sheet, random sheets diced in";
        case CompareVariantKind::SheetExtracted: return "fundamental sheet, random sheets extracted";
    }
    return "?";
}

namespace {

// The surface nodes the smoothing moved, with where it put them.
HeldBack smoothedSurface(const HexMesh& before, const HexMesh& after) {
    HeldBack moved;
    for (std::size_t v = 0; v < before.nodes.size(); ++v)
        if (before.nodes[v] != after.nodes[v]) {
            moved.nodes.push_back(static_cast<Index>(v));
            moved.targets.push_back(after.nodes[v]);
        }
    return moved;
}

// Puts every node still short of its target there: all variants end with the
// one smoothed surface, whatever that does to their hexes.
void finishOnTargets(HexMesh& mesh, const HeldBack& targets) {
    for (std::size_t i = 0; i < targets.nodes.size(); ++i)
        mesh.nodes[static_cast<std::size_t>(targets.nodes[i])] = targets.targets[i];
}

}  // namespace

// a as extracted (and smoothed), b pillowed, c diced up to b's count, d (from
// b) extracted down to a's. Each variant's seconds are the time of its sheet
// operations (d's include b's pillowing). With the boundary fixed the surface
// is smoothed on a copy of the extraction, whose held-back vertices (contour's
// valid start) leave no hex inverted; b's sheet is inserted on that valid
// mesh, then the surface nodes go to their smoothed positions as far as the
// hexes stay valid, the sheet's copies following (as isohex mesh returns its
// held-back vertices), and the rest of the way regardless, so that every
// variant has the same surface on the isosurface.
CompareVariants makeCompareVariants(const Prepared& p, const MeshSettings& settings, std::uint64_t seed,
                                    StageSink& sink) {
    CompareVariants out;
    HexMesh base = contour(p, settings, sink);
    const HexMesh valid = base;
    // Once, before any sheet, so that all four variants share one surface mesh.
    if (settings.fixBoundary) out.boundaryQuads = smoothBoundaryOnIsosurface(base, p, sink);
    const HeldBack surface = smoothedSurface(valid, base);
    auto& v = out.variants;
    v.resize(4);
    v[0] = {CompareVariantKind::NoSheet, base, {}, 0};
    v[1] = {CompareVariantKind::Sheet, valid, {}, 0};
    MeshSettings pillowed = settings;
    pillowed.pillow = true;
    {
        const Stopwatch t;
        std::vector<isohex::PillowResult> passes;
        // (reported as b's "held_back": the surface nodes the smoothing moved)
        v[1].operations =
            toJson(pillowBoundary(v[1].mesh, pillowed, sink, &passes, settings.fixBoundary ? &surface : nullptr));
        finishOnTargets(v[1].mesh, surface);
        v[1].seconds += t.seconds();
    }
    v[2] = {CompareVariantKind::NoSheetDiced, base, {}, 0};
    {
        sink.begin("dice");
        const Stopwatch t;
        v[2].operations = diceUntil(v[2].mesh, v[1].mesh.hexCount(), seed);
        v[2].seconds += t.seconds();
        sink.end("dice", v[2].seconds);
    }
    v[3] = {CompareVariantKind::SheetExtracted, v[1].mesh, {}, 0};
    {
        sink.begin("extract sheets");
        const Stopwatch t;
        v[3].operations = extractUntil(v[3].mesh, base.hexCount(), seed);
        v[3].seconds += t.seconds() + v[1].seconds;
        sink.end("extract sheets", t.seconds());
    }
    return out;
}

OptimizeResult optimizeCompareVariant(CompareVariant& v, const Prepared& p, const MeshSettings& settings,
                                      StageSink& sink) {
    const Stopwatch t;
    OptimizeResult r = optimize(v.mesh, p, settings, sink);
    v.seconds += t.seconds();
    return r;
}

}  // namespace isohex::pipeline

#include "isohex/pipeline/Compare.hpp"

#include <algorithm>
#include <optional>
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

std::optional<CompareVariantKind> variantOfKey(const std::string& key) {
    for (CompareVariantKind k : kAllCompareVariants)
        if (key == variantKey(k)) return k;
    return std::nullopt;
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

namespace {

// b: the extraction as contoured (held-back vertices, no hex inverted), the
// sheet pillowed in, then every surface node on the smoothed surface.
CompareVariant sheetVariant(const HexMesh& valid, const HeldBack& surface, const MeshSettings& settings,
                            StageSink& sink) {
    CompareVariant b{CompareVariantKind::Sheet, valid, {}, 0};
    MeshSettings pillowed = settings;
    pillowed.pillow = true;
    const Stopwatch t;
    std::vector<isohex::PillowResult> passes;
    // (reported as b's "held_back": the surface nodes the smoothing moved)
    b.operations = toJson(pillowBoundary(b.mesh, pillowed, sink, &passes, settings.fixBoundary ? &surface : nullptr));
    finishOnTargets(b.mesh, surface);
    b.seconds += t.seconds();
    return b;
}

// c: a with random sheets diced in up to b's hex count.
CompareVariant dicedVariant(const HexMesh& base, std::size_t target, std::uint64_t seed, StageSink& sink) {
    CompareVariant c{CompareVariantKind::NoSheetDiced, base, {}, 0};
    sink.begin("dice");
    const Stopwatch t;
    c.operations = diceUntil(c.mesh, target, seed);
    c.seconds += t.seconds();
    sink.end("dice", c.seconds);
    return c;
}

// d: b with random non-fundamental sheets extracted down to a's hex count
// (its seconds include b's pillowing).
CompareVariant extractedVariant(const CompareVariant& b, std::size_t target, std::uint64_t seed, StageSink& sink) {
    CompareVariant d{CompareVariantKind::SheetExtracted, b.mesh, {}, 0};
    sink.begin("extract sheets");
    const Stopwatch t;
    d.operations = extractUntil(d.mesh, target, seed);
    d.seconds += t.seconds() + b.seconds;
    sink.end("extract sheets", t.seconds());
    return d;
}

}  // namespace

// With the boundary fixed the surface is smoothed on a copy of the
// extraction, whose held-back vertices (contour's valid start) leave no hex
// inverted; b's sheet is inserted on that valid mesh, then the surface nodes
// go to their smoothed positions as far as the hexes stay valid, the sheet's
// copies following (as isohex mesh returns its held-back vertices), and the
// rest of the way regardless, so that every variant has the same surface on
// the isosurface.
CompareVariants makeCompareVariants(const Prepared& p, const MeshSettings& settings, std::uint64_t seed,
                                    StageSink& sink, const std::vector<CompareVariantKind>& wanted) {
    auto want = [&](CompareVariantKind k) { return std::find(wanted.begin(), wanted.end(), k) != wanted.end(); };
    CompareVariants out;
    HexMesh base = contour(p, settings, sink);
    const HexMesh valid = base;
    // Once, before any sheet, so that all variants share one surface mesh.
    if (settings.fixBoundary) out.boundaryQuads = smoothBoundaryOnIsosurface(base, p, sink);
    const HeldBack surface = smoothedSurface(valid, base);
    std::optional<CompareVariant> b;
    if (want(CompareVariantKind::Sheet) || want(CompareVariantKind::NoSheetDiced) ||
        want(CompareVariantKind::SheetExtracted))
        b = sheetVariant(valid, surface, settings, sink);
    if (want(CompareVariantKind::NoSheet)) out.variants.push_back({CompareVariantKind::NoSheet, base, {}, 0});
    if (want(CompareVariantKind::Sheet)) out.variants.push_back(*b);
    if (want(CompareVariantKind::NoSheetDiced)) out.variants.push_back(dicedVariant(base, b->mesh.hexCount(), seed, sink));
    if (want(CompareVariantKind::SheetExtracted)) out.variants.push_back(extractedVariant(*b, base.hexCount(), seed, sink));
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

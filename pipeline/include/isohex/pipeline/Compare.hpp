#pragma once
// The seed's experiment (dissertation, chapter 5.3): one extraction meshed
// four ways and optimised by one protocol, so that the variants differ only
// in their sheets:
//   a  no sheet
//   b  the fundamental sheet pillowed in
//   c  no sheet, random sheets diced in until the hex count matches b
//   d  the fundamental sheet, random other sheets extracted until the count
//      matches a
// The protocol (settings.fixBoundary, the seed's): the boundary and interface
// quads are smoothed on the isosurface once, on the extraction, before any
// sheet is added, so every variant has the same surface mesh, every node of
// it on the isosurface (the seed's LBIE meshes had their surface improved by
// geometric flow, and pillowing left it unchanged); b's sheet is inserted on
// the extraction as contoured (held-back vertices, no hex inverted) and its
// surface nodes then go to the smoothed surface, as far as the hexes stay
// valid with the sheet's copies following, then the rest of the way (the
// valid start isohex mesh uses); then each variant's surface nodes are fixed
// and its other nodes optimised (pipeline::optimize). Without fixBoundary (compare
// --move-boundary) nothing is smoothed first and surface nodes slide on the
// isosurface while each variant is optimised.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "isohex/core/HexMesh.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/StageSink.hpp"
#include "isohex/smoothing/BoundaryQuads.hpp"

namespace isohex::pipeline {

enum class CompareVariantKind : std::uint8_t { NoSheet, Sheet, NoSheetDiced, SheetExtracted };

struct CompareVariant {
    CompareVariantKind kind = CompareVariantKind::NoSheet;
    HexMesh mesh;
    nlohmann::json operations;  // the sheet operations that made it (report JSON)
    double seconds = 0;         // the time of those operations, and then of its optimisation
};

const char* variantKey(CompareVariantKind kind);    // "a" ... "d"
const char* variantLabel(CompareVariantKind kind);  // "no sheet", ...
// The kind whose key is `key` ("a" ... "d"), or nothing.
std::optional<CompareVariantKind> variantOfKey(const std::string& key);
// Every kind, in the order a, b, c, d.
inline constexpr CompareVariantKind kAllCompareVariants[] = {
    CompareVariantKind::NoSheet, CompareVariantKind::Sheet, CompareVariantKind::NoSheetDiced,
    CompareVariantKind::SheetExtracted};

struct CompareVariants {
    // The surface smoothing every variant shares (with settings.fixBoundary).
    std::optional<smoothing::BoundaryQuadResult> boundaryQuads;
    std::vector<CompareVariant> variants;  // those asked for, in the order a, b, c, d
};

// The variants in `wanted` (any order; each once) before optimisation, from
// one extraction (smoothed on the isosurface first with settings.fixBoundary);
// `seed` draws the random sheets. c's count and d's start are b's mesh, so b
// is made when any of b, c, d is wanted, and kept only when b is. The random
// sheet operations (c and d) are what grows with the square of the mesh;
// `a,b` alone is the comparison with and without the sheet in the time of
// two meshings.
CompareVariants makeCompareVariants(const Prepared& p, const MeshSettings& settings, std::uint64_t seed,
                                    StageSink& sink, const std::vector<CompareVariantKind>& wanted);

// One variant optimised by the protocol (pipeline::optimize with the
// settings' fixBoundary); its seconds grow by the time taken.
OptimizeResult optimizeCompareVariant(CompareVariant& v, const Prepared& p, const MeshSettings& settings,
                                      StageSink& sink);

}  // namespace isohex::pipeline

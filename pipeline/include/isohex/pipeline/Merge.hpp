#pragma once
// Joining the parts of a split scan (Part.hpp) into one conformal mesh: the
// part files of one split, each part once, their nodes on the cuts matched by
// key (whole-grid cell and sheet), never by distance. A cut node that no other
// part has, or a node two parts both own, is refused: the parts would not
// join into one conformal mesh.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/pipeline/CutBands.hpp"

namespace isohex::pipeline {

// One cut, between part `below` and below + 1 (1-based).
struct CutMatch {
    int below = 0;
    std::size_t nodes = 0;     // nodes matched across the cut
    double maxOffset = 0;      // largest distance between the two parts' positions of one node (world units)
};

struct MergeResult {
    HexMesh mesh;
    int parts = 0;
    std::vector<std::size_t> hexesPerPart, nodesPerPart;  // in part order
    std::vector<CutMatch> cuts;                           // in cut order
    std::vector<std::uint8_t> onCut;                      // per merged node: on a cut
    std::optional<CutBandResult> bands;                   // the second pass, unless skipped
    double seconds = 0;
};

// Matched nodes whose two positions differ by more than this fraction of the
// grid step were computed differently by the two parts (a bug, or ghost
// layers too thin for what spread from the cut): refused. Positions agree
// up to rounding, as each part places its window's origin by its own sum.
inline constexpr double kCutOffsetRefused = 1e-6;

// Reads the part files and joins them (node and hex order: part by part,
// a cut node where its lower part has it). Throws isohex::Error naming the
// file and the fault: not a part file, parts of different splits, a part
// missing or given twice, unmatched or duplicated nodes on a cut.
// With `optimiseBands`, the nodes around the cuts are optimised again
// afterwards (CutBands.hpp).
MergeResult mergeParts(const std::vector<std::string>& paths, bool optimiseBands = true);

}  // namespace isohex::pipeline

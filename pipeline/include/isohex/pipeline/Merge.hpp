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
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Prepare.hpp"

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
    std::optional<CutBandResult> bands;                   // the second pass (on the merged boundary), unless skipped
    std::optional<CutBandResult> scanBands;               // with the scan: the passes after it, on the scan's isosurface
                                                          // (before: of the first; after: of the last kept)
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

// Band passes on the scan's isosurface after the one on the merged boundary;
// each starts where the last ended, is kept only as CutBands.hpp says, and
// cannot lower a minimum below the worst-hex target. ch2bet 1 mm from 2
// parts: 0.057 after one, 0.101 after two (single run 0.102).
inline constexpr int kCutBandScanPasses = 2;

// The scan the parts were meshed from, for the band pass: loaded and selected
// with the parts' options, its whole grid chosen (prepareGrid), and the
// surface tolerance (voxels) of the parts' max-min pass.
struct MergeScan {
    const Prepared* prepared = nullptr;
    double surfaceToleranceVoxels = kDefaultSurfaceTolerance;
    double stretchTarget = 0;  // the parts' second max-min target (stretchTargetFor)
};

// As above, and after the band pass a second one whose boundary nodes are
// projected onto the scan's isosurface (the single run's FieldProjector):
// the first lets them slide out of where the frozen cuts left them (on the
// scan alone the band stays there: skull_ct from 2 parts, minimum 0.043
// against the single run's 0.304), the second puts them back on the
// isosurface (alone, the first leaves them up to 2.8 mm off it). Throws isohex::Error when the scan with
// those options gives another whole grid than the parts were cut from (another
// scan, or other options).
MergeResult mergeParts(const std::vector<std::string>& paths, bool optimiseBands, const MergeScan& scan);

}  // namespace isohex::pipeline

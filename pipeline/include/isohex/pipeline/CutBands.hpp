#pragma once
// The second pass of a split scan's optimisation (docs/SPLIT-SCANS.md): each
// part froze the nodes on its cuts while it optimised, so the hexes around a
// cut were optimised against nodes that never moved. After the merge, the
// nodes within a few rings of the cuts, and of every hex below the worst-hex
// target, are optimised again, everything else fixed. With the scan (isohex
// merge --scan) the band's boundary nodes are projected onto its isosurface
// by the projector the single run's optimiser uses (FieldProjector), so they
// slide as in a single run; without, they are kept on the mesh's own
// boundary surface (triangle trees of its quads).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::pipeline {

// Rings of hexes around the cut nodes (and the hexes below the target) whose
// nodes move in the band passes. 8: ch2bet 1 mm merged from 4 parts with the
// scan reached minimum 0.018 with 4 rings, 0.101 with 8 (single run 0.102):
// the frozen cuts left poor hexes whose mending needs room beyond 4 rings.
inline constexpr int kCutBandRings = 8;

// Without the scan: the feature angle the band pass gives adoptBoundary: 180 degrees, so that
// no boundary node is fixed for a sharp edge and every one slides on the
// boundary's quads. A scan's isosurface has no creases at the element size:
// the creases in a band are where the parts froze unoptimised nodes on the
// cut, and fixing them pins the sheet hexes there (skull_ct merged from 4
// parts: minimum 0.050 at adoptBoundary's usual 30 degrees and at 120, 0.303
// with none fixed; the single run's is 0.304).
inline constexpr double kCutBandFeatureAngle = 180.0;

// The scan's isosurface for the band pass: the projector of the single run's
// optimiser over the merged mesh (its surfaces and curves), and the slack the
// max-min pass may leave a surface node off it (world units), as in a single run.
struct CutBandScan {
    const smoothing::SurfaceProjector* projector = nullptr;
    double surfaceSlack = 0;
    // The parts' second max-min target (stretchTargetFor; 0: none): hexes
    // below it seed the band too, and where the band's pass reaches the
    // first target everywhere, the second pass runs on the band as the
    // single run's does (stretchWorstHexes).
    double stretchTarget = 0;
};

struct CutBandResult {
    std::size_t nodes = 0, hexes = 0;  // nodes free to move; hexes around them (the band)
    double minBefore = 0, minAfter = 0;  // lowest scaled Jacobian in the band
    std::size_t invertedBefore = 0, invertedAfter = 0;
    bool kept = false;                 // false: the pass made the band worse and was undone
    double seconds = 0;
};

// Optimises the band of `rings` rings around the nodes flagged in `onCut`
// (one flag per node) and the nodes of the hexes below the worst-hex target in place; keeps the result only if the band has no
// more inverted hexes and no minimum below the smaller of its minimum before and
// the worst-hex target. With `scan`, the
// band's surface and curve nodes are projected onto the scan's isosurface;
// without, they slide on the mesh's own boundary.
CutBandResult optimiseCutBands(HexMesh& mesh, const std::vector<std::uint8_t>& onCut, const CutBandScan* scan = nullptr,
                               int rings = kCutBandRings);

}  // namespace isohex::pipeline

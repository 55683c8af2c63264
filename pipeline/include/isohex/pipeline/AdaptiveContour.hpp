#pragma once
// The adaptive contouring stage (--adaptive): the uniform dual-contouring
// mesh coarsened by octree's 27-tree where the labels allow it, with the
// facts the report and the .vtu carry.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/Sizing.hpp"

namespace isohex::pipeline {

struct AdaptiveFacts {
    int topLevel = 0;                           // levels of the 27-tree above the finest hexes
    std::size_t uniformHexes = 0;               // the uniform mesh at the same finest size
    std::vector<std::size_t> hexesPerLevel;     // contoured hexes filling leaves of each level
    std::size_t cellsAtLabelChanges = 0;        // level-1 cells refined by criterion (a)
    std::vector<std::size_t> cellsForBalance;   // per level: cells refined or promoted by the closure
    std::vector<std::size_t> cellsForGrading;   // per level: parents refined by the grading's dilation
    std::vector<std::size_t> cellsRequested;    // per level: cells any criterion asked for
    int grading = 0;
    SizingFacts sizing;                         // the user sizing and thickness criteria
    double smallestEdge = 0, largestEdge = 0;   // world units, of the contoured mesh
    std::vector<std::uint8_t> hexLevel;         // per hex of the mesh (sheet hexes: their boundary hex's, 0)
};

// Coarsens `uniform` (contour()'s mesh of p.labels, held-back positions
// applied) by the tree of octree::labelChangeRequests ORed with the sizing
// requests (Sizing.hpp), and octree::coarsenDualMesh: the
// boundary and interface hexes and their nodes stay as dual contouring made
// them, uniform regions become coarse hexes and transition templates.
HexMesh coarsenContour(const Prepared& p, HexMesh uniform, const MeshSettings& settings, AdaptiveFacts& facts);

}  // namespace isohex::pipeline

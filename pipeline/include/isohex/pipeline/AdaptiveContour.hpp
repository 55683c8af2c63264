#pragma once
// The adaptive contouring stage (--adaptive): octree's 27-tree over the
// uniform dual-contouring grid, coarse leaves on smooth parts of the surface
// (octree::contourAdaptive), with the facts the report and the .vtu carry.
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/octree/AdaptiveHexes.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/Sizing.hpp"

namespace isohex::pipeline {

struct AdaptiveFacts {
    int topLevel = 0;                           // levels of the 27-tree above the finest hexes
    std::size_t uniformHexes = 0;               // the uniform mesh at the same finest size
    std::vector<std::size_t> hexesPerLevel;     // contoured hexes filling leaves of each level
    octree::FormCounts hexesPerForm;            // the same per level and how the leaf is cut (whole, template)
    octree::FormCounts leavesPerForm;           // the tree's leaves with a contoured hex, per level and cut
                                                // (the tree's also when the uniform mesh is kept)
    std::size_t cellsAtLabelChanges = 0;        // level-1 cells refined by the surface criterion
    std::vector<std::size_t> cellsBySurface;    // per level: cells the surface criterion refined
    // per check round: leaf cells refined at junctions, non-manifold places,
    // inverted hexes and quads off the surface (octree::RefineReason order)
    std::vector<std::array<std::size_t, 4>> cellsByCheck;
    std::size_t unresolved = 0;                 // problems the rounds left
    std::vector<std::size_t> cellsForBalance;   // per level: cells refined or promoted by the closure
    std::vector<std::size_t> cellsForGrading;   // per level: parents refined by the grading's dilation
    std::vector<std::size_t> cellsRequested;    // per level: cells any criterion asked for
    int grading = 0;
    SizingFacts sizing;                         // the user sizing and thickness criteria
    double smallestEdge = 0, largestEdge = 0;   // world units, of the contoured mesh
    std::vector<std::uint8_t> hexLevel;         // per hex of the mesh (sheet hexes: their boundary hex's, 0)
    std::size_t treeHexes = 0;                  // contoured hexes of the tree's mesh
    bool uniformKept = false;                   // the tree saved too little: the uniform mesh is the result
};

// The tree's mesh is kept when it has at most this fraction of the uniform
// mesh's contoured hexes; otherwise the uniform mesh is (its quality is not
// bounded by the transition templates' floor).
inline constexpr double kTreeKeptAtMost = 0.9;

// The adaptive mesh of p.labels (octree::contourAdaptive over the extraction
// domain) from `uniform` (contour()'s mesh of p.labels, held-back positions
// applied), with the user sizing's requests (Sizing.hpp) ORed into the
// surface criterion's: refined regions keep its hexes and nodes, coarse
// leaves straddle the surface where it is smooth and simple.
HexMesh coarsenContour(const Prepared& p, const HexMesh& uniform, const MeshSettings& settings, AdaptiveFacts& facts);

// Whether the tree's mesh replaces the uniform one (kTreeKeptAtMost, or
// settings.keepTree); when not, `facts` says so and gives every hex level 0
// (hexesPerLevel and hexesPerForm then describe the uniform mesh; treeHexes
// and leavesPerForm still describe the tree).
bool keepTree(const HexMesh& tree, const HexMesh& uniform, const MeshSettings& settings, AdaptiveFacts& facts);

}  // namespace isohex::pipeline

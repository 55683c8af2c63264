#pragma once
// Contouring: the hexes of the prepared labels, by dual contouring (every
// boundary vertex on the repaired isosurface) or one hex per grid cell
// centre (Method::Voxel).
#include <cstddef>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/NodeTargets.hpp"
#include "isohex/pipeline/AdaptiveContour.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/StageSink.hpp"

namespace isohex::pipeline {

// Vertices dual contouring placed where they leave a hex inverted, started
// from held-back positions instead (octree::ExtractStats::heldBackAt), with
// where they belong (on the surface, or at their QEF point off it).
struct HeldBack {
    std::vector<Index> nodes;  // ascending
    std::vector<Vec3> targets;
};

// Every vertex whose position inverts a hex is returned at its held-back
// position (octree::ExtractStats::heldBackAt), so that no hex is inverted:
// the pillow places its copies on a valid mesh, then the held-back vertices
// go as far back towards their targets as the hexes allow
// (returnTowardsTargets), and the optimiser moves them the rest of the way.
// With meshExterior the nodes of the outer box are fixed. Reported as the
// stage "extract".
HexMesh contour(const Prepared& p, const MeshSettings& settings, StageSink& sink);
// With settings.adaptive, the uniform mesh coarsened (AdaptiveContour.hpp),
// its facts in `adaptive`. `heldBack`, when given, receives the held-back
// vertices and their targets (none with settings.adaptive: the coarsened
// mesh numbers its nodes anew and starts from the held-back positions).
HexMesh contour(const Prepared& p, const MeshSettings& settings, StageSink& sink, AdaptiveFacts* adaptive,
                HeldBack* heldBack = nullptr);

struct ReturnResult {
    std::size_t heldBack = 0;  // vertices held back by contour
    TargetsResult moved;       // of those: at their target, part of the way, not moved
    TargetsResult copiesFollowed;  // their sheet copies moved by the same displacement (pillowBoundary)
    double seconds = 0;
};

// Takes the held-back vertices towards their targets as far as every hex
// around them stays valid (core's moveTowardsTargets; after the pillow, whose
// sheet gives a surface vertex the room its old hexes did not). Part of the
// stage "pillow" in the report's timings.
ReturnResult returnTowardsTargets(HexMesh& mesh, const HeldBack& heldBack);

}  // namespace isohex::pipeline

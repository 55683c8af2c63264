#pragma once
// Contouring: the hexes of the prepared labels, by dual contouring (every
// boundary vertex on the repaired isosurface) or one hex per grid cell
// centre (Method::Voxel).
#include "isohex/core/HexMesh.hpp"
#include "isohex/pipeline/AdaptiveContour.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/StageSink.hpp"

namespace isohex::pipeline {

// Where putting a boundary vertex on the surface inverts a hex its QEF
// position keeps valid, the vertex is returned at its held-back position
// (octree::ExtractStats::heldBackAt): the pillow and the optimiser start
// from there, and the optimiser moves it onto the surface. With meshExterior
// the nodes of the outer box are fixed. Reported as the stage "extract".
HexMesh contour(const Prepared& p, const MeshSettings& settings, StageSink& sink);
// With settings.adaptive, the uniform mesh coarsened (AdaptiveContour.hpp),
// its facts in `adaptive`.
HexMesh contour(const Prepared& p, const MeshSettings& settings, StageSink& sink, AdaptiveFacts* adaptive);

}  // namespace isohex::pipeline

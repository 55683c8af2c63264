#pragma once
// isohex mesh SURFACE --method sheets, and the surface loading that
// isohex insert-sheet shares with it.
#include <memory>
#include <string>

#include "Pipeline.hpp"
#include "isohex/insertion/SheetInsertion.hpp"

namespace isohex::cli {

// Reads a closed triangle surface (loadSurface's checks) into an AABB tree
// named after the file.
std::shared_ptr<const insertion::TriangleTree> loadTriangleTree(const std::string& path);

// A regular grid 5% larger than the surface's bounding box (element size
// --size, default the surface's mean edge length), two sheets inserted along
// the surface, the outside discarded, then untangling and optimisation with
// surface nodes kept on the triangles; after it a max-min pass on the hexes
// below 0.3 and the volume-balanced fit of the surface nodes (insertion/SurfaceFit.hpp),
// which leaves them slightly off the triangles.
MeshOutcome runSheetMethod(const std::string& input, const MeshSettings& settings, StageSink& sink);

}  // namespace isohex::cli

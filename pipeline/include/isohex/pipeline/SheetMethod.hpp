#pragma once
// Method::Sheets for a closed triangle surface: a regular grid 5% larger than
// the surface's bounding box (element size settings.size, default the
// surface's mean edge length), two sheets inserted along the surface, the
// outside discarded, then untangling and optimisation with surface nodes kept
// on the triangles; after it a max-min pass on the hexes below the target and
// the volume-balanced fit of the surface nodes (sheets/Polish.hpp), which
// leaves them slightly off the triangles. Also the surface loading that
// isohex insert-sheet shares with it.
#include <cstddef>
#include <memory>
#include <optional>
#include <string>

#include "isohex/core/HexMesh.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "isohex/pipeline/StageSink.hpp"
#include "isohex/insertion/SurfaceFit.hpp"
#include "isohex/insertion/SheetGeometry.hpp"
#include "isohex/insertion/SheetInsertion.hpp"
#include "isohex/insertion/TriangleTree.hpp"

namespace isohex::pipeline {

// Reads a closed triangle surface (loadSurface's checks) into an AABB tree
// named after the file.
std::shared_ptr<const insertion::TriangleTree> loadTriangleTree(const std::string& path);

// Enclosed volumes and the distance of boundary nodes to the triangles.
struct SheetFidelity {
    double surfaceVolume = 0, meshVolume = 0;
    double boundaryDistanceMax = 0;
};

struct SheetMethodReport {
    std::string path;
    std::size_t triangles = 0, vertices = 0;
    double surfaceVolume = 0;
    double size = 0;                          // element edge length
    std::size_t gridHexes = 0, gridNodes = 0;  // the regular grid before insertion
    double margin = 0;                        // of the grid around the bounding box, relative
    insertion::InsertResult insert;
    std::optional<smoothing::SmoothingResult> optimization;  // with settings.optimize
    std::optional<WorstHexPassResult> worstHexes;
    std::optional<insertion::VolumeFitResult> surfaceFit;
    SheetFidelity fidelity;
    double seconds = 0;
};

struct SheetMeshing {
    HexMesh mesh;
    SheetMethodReport report;
};

SheetMeshing runSheetMethod(const std::string& input, const MeshSettings& settings, StageSink& sink);

}  // namespace isohex::pipeline

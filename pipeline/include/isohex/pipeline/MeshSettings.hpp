#pragma once
// What decides a mesh: the settings every stage of the pipeline reads, and
// their defaults. The command line fills them (cli/MeshOptions.cpp).
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "isohex/imaging/Selection.hpp"
#include "isohex/imaging/Volume.hpp"

namespace isohex::pipeline {

// How the hexes are made: dual contouring of the sampled grid, one hex per
// grid cell centre (the baseline), or two sheets inserted along a triangle
// surface into a regular grid (surfaces only).
enum class Method { Dual, Voxel, Sheets };

// "dual", "voxel", "sheets": the method's name on the command line and in the report.
std::string_view methodName(Method method);
// The method of that name; none for any other string.
std::optional<Method> parseMethod(std::string_view name);

// Which slab of a scan split into parts to mesh: part `index` (1-based) of
// `count` (Part.hpp, docs/SPLIT-SCANS.md).
struct PartSpec {
    int index = 1, count = 1;
    bool operator==(const PartSpec&) const = default;
};

struct MeshSettings;
// Throws isohex::SettingError when the element size is given and not a
// positive length: the check every method makes for callers other than the
// command line (whose option table refuses such a value already).
void checkElementSize(const MeshSettings& settings);

// The default of the surface tolerance, in voxels: under the 0.1-voxel bound
// the fidelity report checks (fidelity.boundary_nodes_beyond_0_1_voxel).
inline constexpr double kDefaultSurfaceTolerance = 0.09;
inline constexpr int kDefaultRetries = 3;
inline constexpr double kDefaultRetryBelow = 0.05;

struct MeshSettings {
    imaging::LoadOptions load;
    imaging::SelectOptions select;
    std::optional<double> size;   // element edge length in world units
    std::optional<int> level;     // grid step 2^level voxels (exclusive with size)
    Method method = Method::Dual;
    bool keepLargest = false;     // only the largest connected region of each material
    bool fillPits = false;        // fill background pits one grid cell wide (octree::fillOneCellPits)
    // after the non-manifold repair, re-choose its changes so the boundary keeps
    // the components and Euler characteristic of volumeToMesh's surface of the
    // sampled grid where a small search can (octree::matchPolygonTopology)
    bool isosurfaceTopology = false;
    bool pillow = true;
    int boundaryLayers = 1;
    bool meshExterior = false;
    // Coarse hexes wherever the surface allows (octree's 27-tree with
    // transition templates, leaves straddling smooth parts of the surface).
    // Off: one hex per grid point (the uniform mesher, the default).
    bool adaptive = false;
    int adaptiveLevels = 3;       // levels of the tree above the finest hexes (coarse hexes up to 3^levels steps)
    // Grid steps a coarse boundary quad's centre or edge midpoint may lie
    // off its surface before its leaves are refined (octree::AdaptiveSurfaceSettings::deviation).
    double adaptiveDeviation = 0.5;
    // The adaptive mesher's sizing (pipeline/Sizing.hpp); the finest size is `size` (or `level`).
    std::optional<double> maxSize;                            // no cell wider (world units)
    std::vector<std::pair<std::int32_t, double>> labelSizes;  // cells holding label L no wider than S
    std::string sizeImage;                                    // an image of sizes (mm); empty: none
    int grading = 0;                // cells of a level kept around finer ones before a coarser level
    bool thicknessRefinement = true;  // refine where a material is thinner than two cells
    // Write the tree's mesh even when it saves too little against the uniform
    // one (pipeline::kTreeKeptAtMost); off: the uniform mesh is written then.
    bool keepTree = false;
    int exteriorMargin = 3;       // grid steps of background around the object when meshing the exterior
    bool optimize = true;
    // Start the sheet and the optimiser as before the valid start: vertices
    // on their surface wherever their QEF points leave the hexes valid, the
    // sheet's copies along the plain averaged normal, hexes left inverted for
    // the untangler (octree::ExtractOptions::validStart, PillowOptions::
    // turnIntoCorners and stepOnAlone, SmoothingOptions::
    // offSurfaceNodesOntoSurface off, no return of held-back vertices). For
    // comparisons and tests of untangling; off by default (the valid start,
    // --valid-start; the inverted hexes at the optimiser's start with each
    // are in bench/RESULTS.md).
    bool tangledStart = false;
    bool fixBoundary = false;
    // compare fixes the boundary unless --move-boundary (its warnings say so)
    bool fixBoundaryByCompare = false;
    bool worstHexPass = true;     // max-min pass on the hexes the optimiser leaves below worstHexTarget
    bool removeFeatures = true;   // where hexes stay below the certified minimum, remove specks, pockets,
                                  // strands and tunnels finer than an element next to them (FeatureRemoval.hpp)
    // Scaled Jacobian the max-min pass aims every hex at; unset:
    // kDefaultWorstHexTarget, then kStretchTarget where that is reached
    // everywhere (MinQuality.hpp, stretchTargetFor).
    std::optional<double> worstHexTarget;
    // How far (voxels) the max-min pass may leave a surface node off its
    // isosurface to lift a hex below worstHexTarget; unset: kDefaultSurfaceTolerance.
    std::optional<double> surfaceTolerance;
    int randomSheetSeed = 1;
    // When hexes stay inverted (or below retryBelow) after optimisation: how
    // many times to give a grid point next to them another material (topology
    // kept; octree::editNearInvertedHexes) and mesh again; 0 never; unset:
    // kDefaultRetries.
    std::optional<int> retries;
    // The scaled Jacobian below which a hex counts as stuck too; unset:
    // kDefaultRetryBelow; 0: inverted hexes only.
    std::optional<double> retryBelow;
    // The certified minimum scaled Jacobian of the mesh written (--min-quality);
    // unset: the default of the input's kind (pipeline/MinQuality.hpp). The
    // max-min pass aims at the larger of it and worstHexTarget.
    std::optional<double> minQuality;
    // Write the mesh even when it stays below minQuality (the command still
    // fails with its own status).
    bool allowBelow = false;
    // How far (voxels) the bounded boundary relaxation may leave a surface
    // node off its isosurface to lift hexes still below minQuality; unset:
    // kDefaultMaxDeviation (MinQuality.hpp); at most the surface tolerance:
    // no relaxation.
    std::optional<double> maxDeviation;
    // Mesh only this part of the scan, for `isohex merge` (unset: the whole scan).
    std::optional<PartSpec> part;
};

}  // namespace isohex::pipeline

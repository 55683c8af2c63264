#pragma once
// The whole meshing pipeline as one call: load -> select -> octree level and
// labels -> dual contouring -> fundamental sheet -> optimisation. Writing the
// files and printing are left to the commands.
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/imaging/Selection.hpp"
#include "isohex/imaging/Volume.hpp"
#include "isohex/octree/DualContour.hpp"

namespace isohex::smoothing {
struct SurfaceProjector;
}

namespace isohex::pipeline {

// The default of --surface-tolerance, in voxels: under the 0.1-voxel bound
// the fidelity report checks (fidelity.boundary_nodes_beyond_0_1_voxel).
inline constexpr double kDefaultSurfaceTolerance = 0.09;

struct MeshSettings {
    imaging::LoadOptions load;
    imaging::SelectOptions select;
    std::optional<double> size;   // element edge length in world units
    std::optional<int> level;     // grid step 2^level voxels (exclusive with size)
    std::string method = "dual";  // "dual" (dual contouring), "voxel" (one hex per voxel, the baseline), "sheets" (surfaces)
    bool keepLargest = false;     // only the largest connected region of each material
    bool fillPits = false;        // fill background pits one grid cell wide (octree::fillOneCellPits)
    // after the non-manifold repair, re-choose its changes so the boundary keeps
    // the components and Euler characteristic of volumeToMesh's surface of the
    // sampled grid where a small search can (octree::matchPolygonTopology)
    bool isosurfaceTopology = false;
    bool pillow = true;
    int boundaryLayers = 1;
    bool meshExterior = false;
    int exteriorMargin = 3;       // grid steps of background around the object when meshing the exterior
    bool optimize = true;
    bool fixBoundary = false;
    // compare fixes the boundary unless --move-boundary (its warnings say so)
    bool fixBoundaryByCompare = false;
    bool worstHexPass = true;     // max-min pass on the hexes the optimiser leaves below worstHexTarget
    double worstHexTarget = 0.3;  // scaled Jacobian the max-min pass aims every hex at
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
};

inline constexpr int kDefaultRetries = 3;
inline constexpr double kDefaultRetryBelow = 0.05;

// The retries are for a few stuck places: more inverted hexes than this are
// another problem (a surface the sheet cannot follow) and are left as they
// are; of more flat hexes than this, an attempt takes the worst this many.
inline constexpr std::size_t kMaxStuckToRetry = 64;

// Stage reporting: begin(name), fraction updates, end. The pipeline times
// each stage through it.
class StageSink {
public:
    virtual ~StageSink() = default;
    virtual void begin(std::string_view stage) = 0;
    virtual void progress(double fraction) = 0;
    virtual void end(std::string_view stage, double seconds) = 0;
    virtual void note(std::string_view level, const std::string& text) = 0;  // "info" or "warning"
    // A file a library is about to open while loading (a DICOM folder's
    // files, one by one), so a crash can be put down to it.
    virtual void reading(const std::string& /*file*/) {}
};

// A scan loaded and selected, with the sampling grid chosen: everything the
// variants of one input share (isohex compare meshes it several ways).
struct Prepared {
    std::shared_ptr<const imaging::Volume> volume;
    std::shared_ptr<const imaging::Selection> selection;
    std::shared_ptr<const octree::Domain> domain;
    octree::Labels labels;          // repaired, ready for extraction
    // The scan's field with the grid points the repair (or --keep-largest)
    // changed moved across the iso value (octree::RepairedDomain); null when
    // none changed. Extraction contours it, the optimiser keeps the surface
    // nodes of those cells on it; fidelity measures against the scan's field.
    std::shared_ptr<const octree::Domain> repairedDomain;
    const octree::Domain& extractionDomain() const { return repairedDomain ? *repairedDomain : *domain; }
    nlohmann::json report;          // input, selection, grid and repair facts
    std::vector<std::string> warnings;
};

// OpenVDB volumeToMesh's own marching-cubes cell tables (the exact topology
// test of --isosurface-topology, octree::matchPolygonTopology).
const octree::CellEdgeGroups& volumeToMeshTables();

Prepared prepare(const std::string& input, const MeshSettings& settings, StageSink& sink);
// Dual contouring (or voxel hexes) of the prepared labels. Dual contouring
// puts every boundary vertex on the (repaired) isosurface; where that inverts
// a hex its QEF position keeps valid, the vertex is returned at its held-back
// position (octree::ExtractStats::heldBackAt): the sheet and the optimiser
// start from there, and the optimiser moves it onto the surface.
HexMesh extract(const Prepared& p, const MeshSettings& settings, StageSink& sink);
// Pillows the fundamental sheets (unless settings.pillow is off).
nlohmann::json insertSheets(HexMesh& mesh, const MeshSettings& settings, StageSink& sink);
// Untangling and mean-ratio optimisation with surface nodes kept on the isosurface.
// Unless `warnLeftInverted` is false, a warning names the hexes still
// inverted after it.
nlohmann::json optimize(HexMesh& mesh, const Prepared& p, const MeshSettings& settings, StageSink& sink,
                        bool warnLeftInverted = true);

// The max-min pass on the hexes the optimiser left below `target`
// (smoothing/WorstHexes.hpp), timed; returns its report block. Surface nodes
// move only with a projector; `topo` (buildTopology(mesh)) saves building it again.
// `slack`: how far (world units) surface nodes may end off their surface
// (smoothing::WorstHexOptions::surfaceSlack).
nlohmann::json worstHexPass(HexMesh& mesh, const smoothing::SurfaceProjector* projector, double target,
                            double slack = 0, const Topology* topo = nullptr);

// Volume enclosed by each selected material's isosurface vs the mesh's, and
// the distance of boundary and interface nodes to their surfaces.
nlohmann::json fidelity(const HexMesh& mesh, const Prepared& p);
// Volume enclosed by OpenVDB's polygonisation (volumeToMesh) of a field's
// zero set, by the divergence theorem over its polygons.
double isosurfaceVolume(const openvdb::FloatGrid& grid);
// Label maps: the field of the union of the selected labels (0.5 minus the
// sum of their indicators, blurred as theirs are), whose 0.5-isosurface bounds
// the labelled region as a whole.
openvdb::FloatGrid::Ptr labelUnionField(const imaging::Selection& selection);

struct MeshOutcome {
    HexMesh mesh;
    nlohmann::json report;
};
// prepare + extract + insertSheets + optimize, with the report of each.
MeshOutcome runMeshPipeline(const std::string& input, const MeshSettings& settings, StageSink& sink);

}  // namespace isohex::pipeline

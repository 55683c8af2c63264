#pragma once
// Preparation: load the input (a scan, or a closed triangle surface as its
// signed-distance level set), select the materials, choose the element grid
// (by --size, --level, or the coarsest level that keeps the topology), sample
// the labels and repair them so every material's boundary is manifold. What
// it returns is everything the variants of one input share (isohex compare
// meshes it several ways), with the facts the report gives.
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "isohex/imaging/Selection.hpp"
#include "isohex/imaging/Volume.hpp"
#include "isohex/octree/Domain.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/Regions.hpp"
#include "isohex/octree/TopologyMatch.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Part.hpp"
#include "isohex/pipeline/StageSink.hpp"

namespace isohex::pipeline {

// A triangle-surface input's own facts.
struct SurfaceFacts {
    std::size_t triangles = 0, vertices = 0;
    double volume = 0, area = 0;
    bool flipped = false;      // the file was oriented inwards
    std::size_t components = 0;
    long long euler = 0;       // Euler characteristic of the triangles
};

// What was read of a scan: all of it, or (a part of a split scan whose
// format streams) the whole-scan facts slab by slab and then its window.
struct ReadFacts {
    bool window = false;        // only the window's voxels were read to mesh
    bool streamed = false;      // ... and the reader read them alone (else the whole file, cropped)
    std::int64_t voxels = 0;    // voxels held to mesh (the window's, or the scan's)
    std::array<int, 6> box{};   // their index box: min x y z, max x y z
    int summaryPasses = 0;      // slab-by-slab passes through the file before
    std::int64_t summaryReads = 0;
    std::string whole;          // a part that read the scan whole: why
};

// The input as loaded (the report's "input").
struct InputFacts {
    std::string path;
    std::string format, pixelType;
    imaging::VolumeKind kind = imaging::VolumeKind::Intensity;
    std::array<int, 3> dimensions{};
    Vec3 spacing{}, origin{};
    std::array<double, 9> direction{};
    std::array<double, 2> dataRange{};
    std::string seriesUid;                 // DICOM only
    std::optional<SurfaceFacts> surface;   // a triangle surface only
    ReadFacts read;                        // a scan only
};

// The selection (the report's "selection").
struct SelectionFacts {
    std::optional<double> iso;  // intensity only
    bool isoFromOtsu = false;
    bool insideBelow = false;
    struct Material {
        std::int32_t id = 0;
        std::int64_t voxels = 0;
    };
    std::vector<Material> materials;
    std::vector<imaging::DroppedLabel> dropped;
};

// How the grid step was chosen.
enum class GridChoice { Size, Level, Topology };

// A place the isosurface-topology search could not mend, with its box of
// changed grid points in world coordinates.
struct UnmendedPlace {
    Vec3 worldMin{}, worldMax{};
    octree::TopologyMatchReport::Place place;
};

// What the isosurface-topology search did and aimed at.
struct IsosurfaceTopologyFacts {
    octree::TopologyMatchReport match;
    std::vector<UnmendedPlace> unmended;
    std::vector<octree::RegionTopology> isosurface;  // volumeToMesh's surface of the sampled grid, per material
};

struct RepairFacts {
    octree::RepairReport report;  // every repair round added up
    double seconds = 0;
    std::optional<IsosurfaceTopologyFacts> isosurfaceTopology;
};

// The element grid and its labels (the report's "grid").
struct GridFacts {
    GridChoice chosenBy = GridChoice::Topology;
    std::vector<std::string> rejected;  // by topology: why finer and coarser levels were rejected
    std::optional<std::size_t> pointsInSmallerComponentsRemoved;  // with keepLargest
    std::size_t pitsFilled = 0;
    std::size_t repairedFieldPoints = 0;
    std::array<double, 3> stepVoxels{};
    octree::Grid grid;
    std::optional<int> level;  // unless chosen by size
    RepairFacts repair;
    std::vector<octree::RegionTopology> topology;  // of the labels meshed
};

struct PreparedFacts {
    InputFacts input;
    SelectionFacts selection;
    GridFacts grid;
};

// A scan loaded and selected, with the sampling grid chosen and its labels repaired.
struct Prepared {
    std::shared_ptr<const imaging::Volume> volume;
    std::shared_ptr<const imaging::Selection> selection;
    std::shared_ptr<const octree::Domain> domain;  // a SelectionDomain
    octree::Labels labels;                         // repaired, ready for contouring
    // The scan's field with the grid points the repair (or --keep-largest)
    // changed moved across the iso value (octree::RepairedDomain); null when
    // none changed. Contouring follows it, the optimiser keeps the surface
    // nodes of those cells on it; fidelity measures against the scan's field.
    std::shared_ptr<const octree::Domain> repairedDomain;
    const octree::Domain& extractionDomain() const { return repairedDomain ? *repairedDomain : *domain; }
    PreparedFacts facts;
    std::vector<std::string> warnings;
    // With settings.part: the part's window of the whole grid; labels (and
    // facts.grid.grid) are then the window's.
    std::optional<PartWindow> part;
};

Prepared prepare(const std::string& input, const MeshSettings& settings, StageSink& sink);

// The first half of prepare(): the input loaded and selected and the element
// grid chosen (facts.grid.grid), without sampling or repairing labels
// (`labels` stays empty). What isohex estimate needs, at a fraction of the cost.
Prepared prepareGrid(const std::string& input, const MeshSettings& settings, StageSink& sink);

}  // namespace isohex::pipeline

#pragma once
// Fidelity of a mesh to the scan: the volume each selected material's
// isosurface encloses against the mesh's, and the distance of boundary,
// interface and curve nodes to their surfaces.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <openvdb/openvdb.h>

#include "isohex/core/HexMesh.hpp"
#include "isohex/imaging/Selection.hpp"
#include "isohex/pipeline/Prepare.hpp"

namespace isohex::pipeline {

struct MaterialFidelity {
    std::int32_t material = 0;
    double volumeMesh = 0;
    double volumeIsosurface = 0;
    std::optional<double> volumeVoxels;  // label maps: the label's voxels times the voxel volume
};

// Distances of one kind of node to its surface or curve. A projection that
// does not reach it within 3 voxels (or stops where the field is flat) is
// counted apart, not folded into the mean.
struct NodeDistances {
    std::size_t nodes = 0, notProjected = 0;
    std::size_t beyond = 0;  // farther than 0.1 voxel
    double mean = 0, max = 0;
    double p95 = 0;  // the 95th percentile of the projected nodes' distances (nearest rank)
};

// The same boundary nodes measured against the surface the mesh was
// contoured on (the repaired field), where the repair changed grid points.
struct RepairedFidelity {
    std::size_t nodesInRepairedCells = 0;
    std::size_t beyondOrNotProjectedInRepairedCells = 0;
    NodeDistances extracted;
};

struct FidelityResult {
    std::vector<MaterialFidelity> materials;
    bool labels = false;                            // a label map (volumes against voxels too)
    std::optional<double> volumeLabelsIsosurfaces;  // several labels: the sum of their own isosurfaces
    std::string volumeIsosurfaceOf;                 // what volumeIsosurface encloses
    double volumeMesh = 0, volumeIsosurface = 0, volumeVoxels = 0;
    double voxel = 0;                               // the distances' unit in the report
    NodeDistances boundary;
    std::optional<RepairedFidelity> repaired;
    std::optional<NodeDistances> curves;            // when the mesh has curves
    // when it has junction nodes (curve nodes with no named curve): each to
    // the farthest surface around it
    std::optional<NodeDistances> junctions;
};

FidelityResult fidelity(const HexMesh& mesh, const Prepared& p);

// Volume enclosed by OpenVDB's polygonisation (volumeToMesh) of a field's
// zero set, by the divergence theorem over its polygons.
double isosurfaceVolume(const openvdb::FloatGrid& grid);
// Label maps: the field of the union of the selected labels (0.5 minus the
// sum of their indicators, blurred as theirs are), whose 0.5-isosurface bounds
// the labelled region as a whole.
openvdb::FloatGrid::Ptr labelUnionField(const imaging::Selection& selection);

}  // namespace isohex::pipeline

#pragma once
// The mesh's size and memory before any of it is built, so an element size
// far below the voxel spacing is refused in a second instead of running the
// machine out of memory.
#include <string>

#include "isohex/imaging/Selection.hpp"
#include "isohex/imaging/Volume.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/pipeline/MeshSettings.hpp"

namespace isohex::pipeline {

struct MeshMemoryEstimate {
    double hexes = 0;        // estimated hex count of the finished mesh
    double already = 0;      // bytes: the process's peak so far
    double need = 0;         // bytes: already + what the mesh will take
    double budget = 0;       // bytes allowed
    bool budgetGiven = false;  // the budget is the settings' maxMemoryMB (else 80% of physical memory)
};

// The hex count is the selected volume over the element volume (the whole
// grid when meshing the exterior), plus a sixth for the sheet; each hex costs
// about 199 bytes at peak on top of what is already in memory (the slope of
// bench/memory_sweep.py's fit over six element sizes); the estimate takes 220
// and adds the process's peak so far and 16 MB that small meshes take
// whatever their size (test_estimate's phantoms peak 14-17 MB above it). The budget is settings.load.maxMemoryMB, or 80% of the
// machine's memory.
MeshMemoryEstimate estimateMeshMemory(const imaging::Volume& vol, const imaging::Selection& sel,
                                      const octree::Grid& grid, const MeshSettings& settings);

// Bytes at the peak of meshing `hexes` hexes on a grid of `gridPoints`
// points, when `already` bytes are in use: the model above.
double meshPeakBytes(double already, double hexes, double gridPoints);

// Throws isohex::Error naming `input`, the element and voxel sizes, the
// estimate and an element size that would fit, when the estimate exceeds the budget.
void checkMeshMemory(const std::string& input, const imaging::Volume& vol, const imaging::Selection& sel,
                     const octree::Grid& grid, const MeshSettings& settings);

}  // namespace isohex::pipeline

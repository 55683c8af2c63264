#pragma once
// Meshing again kept to a neighbourhood of grid edits (the retries' and
// feature removal's). The edited labels are contoured and pillowed again
// (the whole grid: a small part of the time), then every node that the kept
// mesh has too (same NodeKey: the grid cell of its contouring vertex and its
// sheet) takes its optimised position there; only the nodes within a few
// grid cells of an edit, the nodes the kept mesh does not have and those
// whose class changed move, and only the hexes around them are optimised (a
// submesh whose other nodes are fixed). The rest of the volume keeps its
// optimised nodes: neither the retries nor feature removal optimise the
// whole volume again.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "isohex/pipeline/Part.hpp"
#include "isohex/pipeline/Retries.hpp"
#include "isohex/pipeline/StoredNodeKeys.hpp"

namespace isohex::pipeline {

// How far (grid cells, in each axis) around an edited grid point nodes move:
// first the near neighbourhood, then, when that did not help, the wide one
// (the kept nodes at the near one's border can hold a hex flat).
inline constexpr int kLocalRetryCells = 3;
inline constexpr int kWideRetryCells = 9;
// The scope that optimises the whole volume again (the last resort).
inline constexpr int kWholeVolume = 0;

// The scopes a meshing again tries in turn until one helps: the near
// neighbourhood, the wide one, the whole volume; only the whole volume where
// local meshing does not apply.
std::vector<int> remeshScopes(bool local);

// Whether a retry can be local: one sheet layer at most, no adaptive tree,
// not a part (those number their nodes otherwise), and `best` kept its node
// keys.
bool localRetryApplies(const Meshing& best, const MeshSettings& settings);

// Whether meshLabels keeps the node keys of `m` (Meshing::nodeKeys), freshly
// contoured and pillowed: when the retries or feature removal may mesh it
// again locally (the uniform mesh the adaptive mesher fell back to included).
bool keepsNodeKeys(const Meshing& m, const MeshSettings& settings);

// The keys of the nodes of `contoured`, fresh from contour() on the labels'
// whole grid (the grid cell of each contouring vertex, held back or not).
std::vector<NodeKey> contouredKeys(const HexMesh& contoured, const Prepared& prepared);
// The same, stored (Meshing::nodeKeys).
StoredNodeKeys storedContouredKeys(const HexMesh& contoured, const Prepared& prepared);

// Appends the keys of the sheets' copies (`passes`, pillowBoundary's) to
// `keys`; nothing when the settings pillow nothing.
void addSheetKeys(StoredNodeKeys& keys, const std::vector<isohex::PillowResult>& passes, const HexMesh& mesh,
                  const MeshSettings& settings);

// What a local re-optimisation touched.
struct LocalRegion {
    int cells = 0;              // the neighbourhood's half-width in grid cells
    std::size_t nodes = 0;      // nodes free to move
    std::size_t hexes = 0;      // hexes optimised (those with a free node)
    std::size_t carried = 0;    // nodes that took their position from the kept mesh
    std::size_t meshHexes = 0;  // hexes of the whole mesh, for comparison
    double seconds = 0;
    OptimizeResult optimization;  // of the submesh
};

// Contours and pillows the edited labels `prepared`, starts the mesh from the
// optimised `kept` mesh (whose nodeKeys must be set) and optimises the
// neighbourhood of `cells` grid cells around the grid points `edited`
// (indices into the labels' grid), as above. The result keeps its node keys;
// its optimization is kept's (the whole-mesh run); the local one is in `region`.
// Its stages report as "extract_again", "pillow_again" and "optimize_again".
Meshing meshLabelsNear(Prepared prepared, const MeshSettings& settings, StageSink& sink, const Meshing& kept,
                       const std::vector<std::size_t>& edited, int cells, LocalRegion& region);

// The grid points whose material differs between `before` and `after` (the
// same grid): what a local meshing of `after` must free around.
std::vector<std::size_t> changedPoints(const octree::Labels& before, const octree::Labels& after);

// The report's record of a local meshing.
RetryRegion regionRecord(const LocalRegion& region);

}  // namespace isohex::pipeline

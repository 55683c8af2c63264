#pragma once
// A labelled grid as OpenVDB's marching-cubes polygoniser (volumeToMesh)
// sees it: its cell tables, and the parts of each material its surface keeps
// apart. The non-manifold repair and the topology matching compare against
// exactly that surface.
#include <cstdint>
#include <vector>

#include "isohex/octree/Labels.hpp"
#include "isohex/octree/Regions.hpp"
#include "isohex/octree/TopologyMatch.hpp"

namespace isohex::octree {

// volumeToMesh's own marching-cubes cell tables (read from OpenVDB's
// volume_to_mesh_internal), for the exact topology test of
// matchPolygonTopology and flipKeepsPolygonTopology.
const CellEdgeGroups& volumeToMeshTables();

// The parts of every material that volumeToMesh keeps apart, as one id per
// grid point (-1 for background), for repairNonManifold's `regions`: points
// of a material are in one part when 6-adjacent or on the inner side of one
// connected component of the volumeToMesh surface of the material's points
// (grid points of the material inside, the rest outside). Each surface
// polygon is dual to the grid edge it crosses, which names the point on its
// inner side. `surfaces` (optional): each material's components and Euler
// characteristic of that surface, in material order.
std::vector<std::int32_t> marchingCubesRegions(const Labels& labels, std::vector<RegionTopology>* surfaces = nullptr);

}  // namespace isohex::octree

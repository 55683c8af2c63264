#pragma once
// Non-manifold repair: changing the labels of a few grid points until every
// material's region, and every interface between two materials, is a
// 2-manifold (no two regions touch along only an edge or at a corner).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "isohex/octree/Domain.hpp"
#include "isohex/octree/Labels.hpp"

namespace isohex::octree {

struct CellEdgeGroups;  // a polygoniser's cell tables (TopologyMatch.hpp)

struct RepairReport {
    std::size_t nonManifoldBefore = 0;   // 2x2x2 blocks whose regions were not manifold
    std::size_t pointsAdded = 0;         // grid points given to a region
    std::size_t pointsRemoved = 0;       // grid points taken from a region
    int rounds = 0;
};

// Counts 2x2x2 blocks where some material's region (or its complement) is not
// 6-connected inside the block: exactly the places where the boundary of the
// union of the points' cubes has a non-manifold edge or vertex.
std::size_t countNonManifoldBlocks(const Labels& labels);

// Flips grid points until every material region is 2-manifold; iterates to a
// fixpoint. Deterministic. Throws isohex::Error if no fixpoint is found.
// For each bad block it prefers flips that keep the topology of the surface
// marching cubes draws (components, tunnels, cavities of every region: see
// simpleFlip in NonManifoldRepair.cpp), moving a one-point pocket or speck
// by a point where it must, then the flip closest to the surface (smallest
// |value|).
// `regions` (optional, one id per grid point): the parts marching cubes keeps
// apart, e.g. the components of OpenVDB's volumeToMesh surface; points of one
// material with different ids stay apart even where they touch along an edge
// or at a corner. Without it, each material's 26-connected components.
// `marchingCubes` (optional): the polygoniser's tables; with them a flip
// counts as topology-keeping only when flipKeepsPolygonTopology says so (the
// 26/6 digital model above is only close to marching cubes: many of its
// "simple" flips change the polygoniser's surface, with changes that happen
// to cancel). Not used by the pipeline: with it, the contacts that no single
// flip or pocket move can mend exactly no longer cancel.
// --isosurface-topology instead re-chooses the repair's changes afterwards
// (matchPolygonTopology).
RepairReport repairNonManifold(Labels& labels, const Domain& domain,
                               const std::vector<std::int32_t>* regions = nullptr,
                               const CellEdgeGroups* marchingCubes = nullptr);

}  // namespace isohex::octree

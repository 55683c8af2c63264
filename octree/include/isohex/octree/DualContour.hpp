#pragma once
// Dual contouring of labelled grid points into hexahedra (LBIE's uniform
// stage; Ju et al. 2002 for dual contouring): one hex per labelled grid point
// whose corners are the dual vertices of the 8 grid cells around it (QEF
// minimisers where the surface crosses a cell, moved onto the surface), or
// with cell centres the grid's own cubes (voxel meshing).
#include <cstddef>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Progress.hpp"
#include "isohex/octree/Domain.hpp"
#include "isohex/octree/Labels.hpp"

namespace isohex::octree {

struct ExtractOptions {
    bool meshExterior = false;   // also mesh background points (material 0) out to the grid box
    double qefTruncation = 0.1;  // singular values below this fraction of the largest are dropped
    double cellMargin = 0.02;    // QEF vertices are kept this fraction of a cell inside their cell
    // Put every vertex at its cell centre instead of the QEF minimiser: the hexes
    // are then the grid's own cubes around each labelled point (voxel meshing,
    // the stair-stepped baseline of bone biomechanics).
    bool cellCentres = false;
    // Move each QEF vertex of a cell between two materials onto their surface
    // with a few Newton steps (kept inside the cell): the QEF minimiser of a
    // curved surface lies off it by a fraction of a cell. A cell where the
    // outside meets two or more materials goes onto the surface of their
    // union (Domain::unionValue) instead, where the domain knows it.
    bool projectVertices = true;
    // Hold back every crossed cell's vertex that leaves a hex inverted, along
    // surface point -> QEF point -> cell centre, so that no hex is inverted
    // (ExtractStats::heldBackAt). Off: only vertices moved onto the surface,
    // no farther than their QEF point, and hexes inverted with the QEF
    // points too stay inverted (the start before the optimiser had a valid
    // one: for comparisons and tests of untangling).
    bool validStart = true;
    Progress progress;
};

struct ExtractStats {
    std::size_t crossedCells = 0;
    std::size_t clampedVertices = 0;  // QEF minimisers that fell outside their cell
    // Nodes (ascending) of crossed cells whose position (on the surface, or
    // the QEF point where the vertex is not projected) leaves a hex inverted.
    // The mesh has them at that position; heldBackAt (same order) is a point
    // on the path from there through the QEF point to the cell's centre, as
    // near the start of the path as keeps every hex valid (the mesher starts
    // its sheet and optimiser from there). With the held-back positions no
    // hex is inverted: at the centres the hexes are the grid's cubes.
    std::vector<Index> heldBack;
    std::vector<Vec3> heldBackAt;
};

// One hex per labelled point (also material-0 points with meshExterior), in
// VTK order with positive orientation; boundary and interface nodes are
// classified (classifyBoundaryNodes). The labels must be manifold, and every
// grid point should have its label's sign in `domain` (after a repair, pass a
// RepairedDomain) so that the surface crosses every cell between two labels.
// Boundary vertices are on the surface, also those whose move there inverts a
// hex (see ExtractStats::heldBackAt for positions that invert none).
HexMesh dualContourHexes(const Labels& labels, const Domain& domain, const ExtractOptions& opt = {},
                         ExtractStats* stats = nullptr);

}  // namespace isohex::octree

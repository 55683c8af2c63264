#pragma once
// From a sampled solid to hexahedra (LBIE's uniform stage; Ju et al. 2002 for
// dual contouring): label the grid points, make the labelled regions 2-manifold,
// then one hex per labelled grid point whose corners are the dual vertices of
// the 8 grid cells around it (QEF minimisers where the surface crosses a cell).
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Progress.hpp"
#include "isohex/octree/Domain.hpp"
#include "isohex/octree/TopologyMatch.hpp"  // CellEdgeGroups (the repair), matchPolygonTopology

namespace isohex::octree {

// Material label per grid point (x fastest), 0 = background.
struct Labels {
    Grid grid;
    std::vector<std::int32_t> material;
};

// Samples materialAt at every grid point (parallel). Points on the grid's
// outer layer are forced to background so every region is closed, unless
// `keepBorder` (used when the exterior itself is meshed out to the box).
Labels sampleLabels(const Domain& domain, const Grid& grid, bool keepBorder = false);

// Keeps, for every material, only its largest 6-connected region of grid
// points (the others become background): drops the specks of noise that an
// intensity threshold leaves around an organ. Returns the points removed.
std::size_t keepLargestComponents(Labels& labels);

// Fills one-grid-cell pits of the background: a background point with exactly
// five face neighbours of one material (the sixth is background) joins that
// material, and again for the points this uncovers, until none is left, so a
// well one cell wide is filled to its rim. Such a pit's floor is a boundary
// quad whose four corners each have three boundary quads; the fundamental
// sheet then needs a convex hex over a nearly flat floor with four 90-degree
// corners, which no node placement gives (the last inverted hexes on ch2bet).
// The filled points are simple (dead ends of the background, 26-joined to
// the material), so no region gains or loses a component, tunnel or cavity;
// two pits facing each other (a two-point cavity) are left alone. Points on
// the grid's outer layer are never filled. Returns the points filled.
std::size_t fillOneCellPits(Labels& labels);

// One grid point given another material.
struct PointEdit {
    std::size_t point = 0;
    std::int32_t from = 0, to = 0;
};

// The grid edit behind the pipeline's retry for hexes the optimiser leaves
// inverted. Such hexes sit where the grid's shape asks the sheet for a convex
// hex no node placement gives: a bump one point wide at a junction of
// materials, a pit, a notch. Near each position (fractional grid coordinates
// of an inverted hex's centre), among the 27 points around it that are not
// `frozen` and not on the grid's outer layer, the most exposed one (fewest
// face neighbours of its own material, at most `maxSame`) takes the material
// most of its face neighbours hold, provided the change is simple for both
// materials (every material keeps its components, tunnels and cavities; a
// point joining or leaving the background is also simple for the union of
// all materials, so the exterior and the pockets of background between
// materials keep theirs) and leaves the 8 blocks around the point manifold.
// Positions off the grid (or not finite) are skipped. At most one edit per place:
// a position with an edit of this call among its 27 points is skipped.
// Returns the edits, in the order made.
std::vector<PointEdit> editNearInvertedHexes(Labels& labels, const std::vector<std::array<double, 3>>& positions,
                                             const std::vector<std::size_t>& frozen = {}, int maxSame = 2);

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
// simpleFlip in Labels.cpp), moving a one-point pocket or speck by a point
// where it must, then the flip closest to the surface (smallest |value|).
// `regions` (optional, one id per grid point): the parts marching cubes keeps
// apart, e.g. the components of OpenVDB's volumeToMesh surface; points of one
// material with different ids stay apart even where they touch along an edge
// or at a corner. Without it, each material's 26-connected components.
// `marchingCubes` (optional): the polygoniser's tables; with them a flip
// counts as topology-keeping only when flipKeepsPolygonTopology says so (the
// 26/6 digital model above is only close to marching cubes: on ch2bet at
// 2 mm about a thousand of its "simple" flips change volumeToMesh's surface,
// with changes that happen to cancel). Not used by the pipeline: with it
// the ~15 contacts of ch2bet at 2 mm that no single flip or pocket move can
// mend exactly no longer cancel (see docs/DESIGN.md). --isosurface-topology
// instead re-chooses the repair's changes afterwards (matchPolygonTopology).
RepairReport repairNonManifold(Labels& labels, const Domain& domain,
                               const std::vector<std::int32_t>* regions = nullptr,
                               const CellEdgeGroups* marchingCubes = nullptr);

// Topology of each material region's boundary: connected components and
// Euler characteristic (a closed surface of genus g per component has chi = 2 - 2g).
struct RegionTopology {
    std::int32_t material = 0;
    std::size_t components = 0;
    long long euler = 0;
    std::size_t points = 0;              // grid points in the region
    bool operator==(const RegionTopology&) const = default;
};
std::vector<RegionTopology> regionTopology(const Labels& labels);
std::string describe(const std::vector<RegionTopology>& t);

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
    Progress progress;
};

struct ExtractStats {
    std::size_t crossedCells = 0;
    std::size_t clampedVertices = 0;  // QEF minimisers that fell outside their cell
    // Nodes (ascending) whose move onto the surface inverts a hex that their
    // QEF positions leave valid. The mesh has them on the surface; heldBackAt
    // (same order) is the position between the QEF point and the surface
    // point, as near the surface as keeps every hex around valid (the mesher
    // starts its sheet and optimiser from there).
    std::vector<Index> heldBack;
    std::vector<Vec3> heldBackAt;
};

// One hex per labelled point (also material-0 points with meshExterior), in
// VTK order with positive orientation; boundary and interface nodes are
// classified (classifyBoundaryNodes). The labels must be manifold, and every
// grid point should have its label's sign in `domain` (after a repair, pass a
// RepairedDomain) so that the surface crosses every cell between two labels.
// Boundary vertices are on the surface, also those whose move there inverts a
// hex (see ExtractStats::heldBackAt).
HexMesh dualContourHexes(const Labels& labels, const Domain& domain, const ExtractOptions& opt = {},
                         ExtractStats* stats = nullptr);

// --- choosing the grid
// LBIE's test of whether coarse cells (2 fine steps wide) may replace their 8
// children: on the fine labels, a coarse edge whose ends agree must not change
// material at its midpoint, a coarse face or cell whose corners all agree must
// not differ at its centre, and no coarse face or cell may carry an ambiguous
// (diagonal) pattern. Returns the number of coarse cells that fail.
std::size_t lbieFailures(const Labels& fine);

struct LevelChoice {
    int level = 0;                        // grid step = 2^level base steps
    Grid grid;
    std::vector<RegionTopology> topology; // at the chosen level (after repair)
    std::vector<RegionTopology> reference;// at level 0 (after repair)
    double volumeChange = 0;              // relative change of labelled volume vs level 0
    std::vector<std::string> notes;       // why finer / coarser levels were rejected
};

struct LevelOptions {
    int maxLevel = 6;
    double maxVolumeChange = 0.05;        // a coarser level must keep the labelled volume within this
    std::size_t minPoints = 64;           // and keep at least this many labelled points per material
    bool cellTests = true;                // also require LBIE's per-cell topology tests to pass
};

// The coarsest level whose repaired regions have the same components and Euler
// characteristics as the finest (base) grid and whose labelled volume is
// within maxVolumeChange: the LBIE starting level chosen by topology.
LevelChoice chooseLevel(const Domain& domain, const Grid& base, const LevelOptions& opt = {});

// The grid `level` steps coarser than `base` over the same box (same origin).
Grid coarsen(const Grid& base, int level);

}  // namespace isohex::octree

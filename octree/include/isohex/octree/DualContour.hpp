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
// The cell tables of a marching-cubes polygoniser. edgeGroups: for each of
// the 256 sign patterns of a cell (bit v set when corner v is inside; corners
// numbered (0,0,0) (1,0,0) (1,0,1) (0,0,1) (0,1,0) (1,1,0) (1,1,1) (0,1,1)),
// entry 0 the number of surface vertices in the cell and entry e (1..12) the
// vertex (1-based, 0 when the edge is not crossed) on cell edge e, edges 0-1
// 1-2 3-2 0-3 4-5 5-6 7-6 4-7 0-4 1-5 2-6 3-7. ambiguousFace: 0, or the face
// (1..6: -z +x +z -x -y +y) of an ambiguous pattern; a cell whose neighbour
// across that face has the opposite face ambiguous (1-3, 2-4, 5-6) takes
// the vertices of its inverted pattern. OpenVDB's volumeToMesh has both
// (volume_to_mesh_internal::sEdgeGroupTable, sAmbiguousFace); the pipeline
// passes them in.
struct CellEdgeGroups {
    std::array<std::array<std::uint8_t, 13>, 256> edgeGroups{};
    std::array<std::uint8_t, 256> ambiguousFace{};
};

// Whether grid point (i, j, k) taking material `to` keeps the components
// and Euler characteristic of the polygoniser's surface of its material and
// of `to` (each material's points inside, all others outside), decided from
// the 9x9x9 points around it (the repair's preferred flips). *eulerChange,
// if given: the exact change of the sum of the two surfaces' Euler
// characteristics.
bool flipKeepsPolygonTopology(const Labels& labels, int i, int j, int k, std::int32_t to,
                              const CellEdgeGroups& table, long long* eulerChange = nullptr);

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

// After repairNonManifold (the pipeline's --isosurface-topology): re-chooses
// the repair's changes so that the boundary keeps the components and Euler
// characteristic of the surface a marching-cubes polygoniser (`table`, e.g.
// OpenVDB's volumeToMesh) draws around `sampled`, where a small search finds
// how. The points where `repaired` differs from `sampled` are taken in
// groups (changes within 2 points of each other on every axis), in grid
// order, each checked exactly from the state the earlier groups left (the
// polygon surface of every material in a window around the group, mcKeeps).
// A group whose change alters it gets the search: the repair's change plus
// 1, 2 or 3 flips of points next to the group (3 only among at most 80
// candidate flips), then 1 or 2 flips of points within 2 of it, never of a
// point next to another group, that leave every block around them manifold
// and keep the surface (at most 150,000 trials per search); of those with
// the fewest flips, the one nearest the sampled labels (fewest points off
// them, then smallest |field| there). A group more than 12 points wide is
// taken part by part (its 26-connected parts, wide ones cut into boxes 8
// points wide), each part checked from the state the earlier parts left and
// searched the same way, with the later parts judged as the repair leaves
// them; if its parts leave a block bad, the group keeps the repair's whole
// change. What that search cannot mend gets a deeper one: a beam search over
// sets of up to 10 options, each a flip of a boundary point within 2 or a
// move that keeps a one-point speck or pocket of the sampled labels apart
// (several points), scored by how far
// the polygon surface in the window is from before and by the blocks left
// bad, the first manifold set that keeps the surface (checked exactly)
// winning (docs/DESIGN.md, "The deep search"). When the beam finds none,
// seeded annealing chains toggle the same options at random, and a set they
// reach is shrunk while it stays exact (docs/DESIGN.md, "Annealing"). A
// group or part no search can mend keeps the repair's change and is listed
// in `unmended`.
// So no window is wider than 12 + 4 + 8 points. `repaired` stays manifold
// (checked; if not, it is left as it was and the report says discarded).
// Deterministic, single-threaded.
struct TopologyMatchReport {
    std::size_t groups = 0;           // groups of changed points
    std::size_t groupsChanging = 0;   // whose change (the repair's) altered the polygon surface
    std::size_t groupsMatched = 0;    // of those, mended: the group's change now keeps it
    std::size_t pointsChanged = 0;    // points whose label differs from the repair's now
    bool discarded = false;           // the result was not manifold: the repair's labels are kept
    std::size_t deepTrials = 0;       // sets the deep search probed: its beam, exact checks and shrinking of annealed sets
    std::size_t annealSteps = 0;      // steps of its annealing, clashing ones included (at most 120,000 in one run)
    // The groups (or parts of wide groups) the search could not mend, in the
    // order they were taken: their changed points' box on the grid (lowest
    // point, highest point), how many points, and the Euler change of the
    // polygon surface (all materials) the repair's change makes there.
    struct Place {
        std::array<int, 3> lo{}, hi{};
        std::size_t points = 0;
        long long eulerChange = 0;
    };
    std::vector<Place> unmended;
};
TopologyMatchReport matchPolygonTopology(Labels& repaired, const Labels& sampled, const Domain& domain,
                                         const CellEdgeGroups& table);

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

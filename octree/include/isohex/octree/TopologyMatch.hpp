#pragma once
// Keeping the topology of the isosurface a marching-cubes polygoniser (e.g.
// OpenVDB's volumeToMesh) draws around the sampled labels: the polygoniser's
// cell tables, the exact test of whether one grid point's flip keeps that
// surface's components and Euler characteristic, and the re-choice of the
// non-manifold repair's changes that keeps it (--isosurface-topology).
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "isohex/octree/Domain.hpp"

namespace isohex::octree {

struct Labels;

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
// winning. When the beam finds none,
// seeded annealing chains toggle the same options at random, and a set they
// reach is shrunk while it stays exact (docs/DESIGN.md, "`--isosurface-topology`
// is a global step after the repair, and an option"). A
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

}  // namespace isohex::octree

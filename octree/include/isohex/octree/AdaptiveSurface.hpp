#pragma once
// The adaptive mesher with coarse leaves on the surface: a 27-tree whose
// leaves of any level may straddle a boundary or an interface (generalised
// dual contouring over the tree), checked and refined until the boundary is
// manifold, every hex valid and every coarse boundary quad near the surface.
//
// Flow: the surface criterion (SurfaceCoarsening.hpp), OR-ed with any other
// requests (user sizing) -> closeRefinement -> the leaves' hexes with the
// label at their centroid (AdaptiveHexes.hpp) -> node placement -> checks ->
// more requests, until a round adds none. Fully refined, the tree is the
// uniform dual-contouring mesh (manifold, valid), so the rounds end.
//
// Node placement: a node whose eight surrounding leaves are all level 0 is
// the uniform mesh's node (position and class), so refined regions are the
// uniform mesh bit for bit. Any other node on a boundary or interface quad
// goes where the surface crosses the segments between the centroids of the
// hexes on either side of its quads (the segment's mirror image past the
// quad on the boundary), averaged and then moved onto the material's zero set
// by Newton steps (surface nets); its class is Surface with the id of the
// uniform mesh's surface of that material pair. Other nodes stay at their
// lattice positions, interior.
//
// Checks (each asks for the leaves around the offending nodes, or the leaf
// of the offending hex, to be refined):
// - junction: a moved node on quads of two surfaces, or of a material pair
//   the uniform mesh has no surface for (curves stay fine);
// - non-manifold: an edge of a surface's quads in other than two of them, or
//   a node whose quads of one surface are not one fan;
// - inverted: a hex with a moved node and a non-positive Jacobian
//   determinant (corners and centre, as validate() asks);
// - deviation: a quad with a moved node whose centre or an edge midpoint is
//   farther than `deviation` grid steps from its surface (|f| / |grad f|).
#include <array>
#include <cstddef>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/octree/AdaptiveHexes.hpp"
#include "isohex/octree/Domain.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/RefinementTree.hpp"
#include "isohex/octree/SurfaceCoarsening.hpp"

namespace isohex::octree {

struct AdaptiveSurfaceSettings {
    int maxLevel = 3;         // coarse hexes up to 3^maxLevel grid steps
    double deviation = 0.5;   // grid steps: farthest a coarse boundary quad's centre or edge midpoint may be from its surface
    int maxRounds = 12;       // check rounds after the first assembly
    int grading = 0;          // closeRefinement's grading (Grading.hpp)
};

enum class RefineReason : std::uint8_t { Junction, NonManifold, Inverted, Deviation };
inline constexpr int kRefineReasons = 4;

struct AdaptiveRound {
    std::array<std::size_t, kRefineReasons> cells{};  // leaf cells newly requested, per RefineReason
};

struct AdaptiveSurfaceResult {
    AdaptiveMesh mesh;
    RefinementTree tree;                      // the final tree
    std::vector<std::size_t> criterionCells;  // per level (index 0 unused): cells the surface criterion requested
    std::vector<AdaptiveRound> rounds;        // one per round that requested cells
    std::size_t unresolved = 0;  // problems left after the last round (none can be fixed by refining, or rounds ran out)
};

// The adaptive mesh of `labels` (manifold, the labels dualContourHexes made
// `uniform` from, held-back positions applied) over `domain` (the extraction
// domain: its signs follow the labels). `extra` requests are OR-ed with the
// surface criterion's.
AdaptiveSurfaceResult contourAdaptive(const Labels& labels, const Domain& domain, const HexMesh& uniform,
                                      const AdaptiveSurfaceSettings& settings, const RequestMasks& extra = {});

}  // namespace isohex::octree

#pragma once
// The retry loop: hexes still inverted, or left nearly flat, after
// optimisation sit where the grid's shape asks the sheet for a convex hex no
// node placement gives (a one-point bump at a junction of materials, a pit).
// Give a grid point there another material (simple: no topology change;
// octree::editNearInvertedHexes) and mesh again; keep the result when it is
// better (Stuck::betterThan).
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/pipeline/AdaptiveContour.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "isohex/pipeline/Pillow.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/StageSink.hpp"
#include "isohex/pipeline/StoredNodeKeys.hpp"
#include "isohex/pipeline/StuckHexes.hpp"

namespace isohex::pipeline {

// The retries are for a few stuck places: more inverted hexes than this are
// another problem (a surface the sheet cannot follow) and are left as they
// are; of more flat hexes than this, an attempt takes the worst this many.
inline constexpr std::size_t kMaxStuckToRetry = 64;

// One meshing of prepared labels: contour, pillow, optimise.
struct Meshing {
    Prepared prepared;
    HexMesh mesh;
    std::size_t contouredHexes = 0, contouredNodes = 0;  // the report's "extracted"
    PillowResult pillow;
    OptimizeResult optimization;
    std::optional<AdaptiveFacts> adaptive;  // settings.adaptive: the tree's facts, a level per hex
    std::optional<PartNodes> partNodes;  // with prepared.part: the keys of the part's nodes
    // With local retries (LocalRetry.hpp, keepsNodeKeys): each node's key, so
    // that a meshing again can start from this mesh's optimised nodes without
    // contouring it a second time. Empty otherwise, and once the retries and
    // feature removal are over.
    StoredNodeKeys nodeKeys;
};

struct RetryEdit {
    std::array<int, 3> gridPoint{};
    Vec3 at{};
    std::int32_t from = 0, to = 0;
};

// Where a retry re-optimised (LocalRetry.hpp): the rest kept its nodes.
struct RetryRegion {
    std::size_t nodes = 0, hexes = 0, meshHexes = 0, carried = 0;
    int cells = 0;  // the neighbourhood's half-width in grid cells (LocalRetry.hpp)
    std::size_t invertedBefore = 0, untangleSweeps = 0, sweeps = 0;
    double seconds = 0;
};

struct RetryAttempt {
    int attempt = 0;
    StuckCounts before;
    std::vector<RetryEdit> edits;
    bool kept = false;
    std::optional<std::string> notMeshedBecause;  // the attempt stopped before meshing
    std::optional<StuckCounts> after;             // when it meshed
    std::optional<RetryRegion> region;            // when it optimised a neighbourhood only
};

struct RetryResult {
    int allowed = 0;
    double floor = 0;
    std::vector<RetryAttempt> attempts;
    std::size_t pointsEdited = 0;  // in the attempts kept
    std::size_t meshedAgain = 0;
    double seconds = 0;
    Stuck stuck;                   // what is left in the mesh kept
};

// Contours, pillows and optimises (without warning of inverted hexes: the
// retries count and warn after them). A part's cut nodes are left Fixed
// (unfreezeCutNodes gives them their classes back once nothing moves nodes).
Meshing meshLabels(Prepared prepared, const MeshSettings& settings, StageSink& sink);

// Retries where `best` has stuck hexes (settings.retries times at most, with
// Method::Dual only), replacing `best` by every better meshing.
RetryResult retryStuckHexes(Meshing& best, const MeshSettings& settings, StageSink& sink);

// Warns of the hexes inverted or below the retries' floor in `best.mesh`,
// adding the warnings to `warnings`. Called on the mesh written, after the
// means that follow the retries (the relaxation, feature removal), which may
// lift what the retries left: a warning names only hexes the file has.
void warnStuckHexes(const Meshing& best, const RetryResult& retries, const MeshSettings& settings, StageSink& sink,
                    std::vector<std::string>& warnings);

}  // namespace isohex::pipeline

#pragma once
// Removal of features finer than an element, the last of the certified
// minimum's means: where hexes are still below Q after the optimiser, the
// retries and the bounded relaxation, a speck, pocket, one-point strand or
// tunnel of the element grid's labels next to them is given the label around
// it (never a material's only piece), the labels are repaired and meshed
// again, optimising only around the changed grid points (LocalRetry.hpp),
// and the result is kept when its worst hex is better. Each feature removed is reported with its
// position and volume. Off when the mesh reaches Q.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "isohex/pipeline/LocalFeatures.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/MinQuality.hpp"
#include "isohex/pipeline/Retries.hpp"
#include "isohex/pipeline/StageSink.hpp"

namespace isohex::pipeline {

// The hexes below Q whose neighbourhoods are searched, worst first.
inline constexpr std::size_t kMaxHexesForFeatures = 256;
// Rounds of junction edits at most (each kept only when better).
inline constexpr int kJunctionEditRounds = 3;

struct RemovedFeature {
    LocalShape shape = LocalShape::Speck;
    std::int32_t material = 0, replacedBy = 0;
    Vec3 at{};           // world coordinates (mm for a scan)
    double volume = 0;   // world units cubed
    std::size_t gridPoints = 0;
};

struct FeatureRemovalResult {
    std::vector<RemovedFeature> features;  // the features given the label around them
    std::optional<std::string> notMeshedBecause;
    bool kept = false;                     // the mesh written has them removed
    double minBefore = 0, minAfter = 0;    // degenerate as 0
    std::size_t belowBefore = 0, belowAfter = 0;
    std::size_t repairedPoints = 0;        // points the repair changed after the removal
    std::optional<RetryRegion> region;     // the neighbourhood optimised again (LocalRetry.hpp)
    double seconds = 0;
};

// Stage "features" of the dual pipeline, after "relax": none when the mesh
// reaches Q, with --keep-features, --no-optimize or another method. When it
// keeps the new meshing, `best` and `relaxation` become the new ones.
std::optional<FeatureRemovalResult> removeFineFeatures(Meshing& best, const MeshSettings& settings, StageSink& sink,
                                                       std::optional<RelaxationResult>& relaxation);

}  // namespace isohex::pipeline

#pragma once
// The pillow stage: the fundamental boundary sheet (pillowAllMaterials), one
// or more layers of hexes along every material's boundary, so no hex has two
// faces on one surface.
#include <cstddef>
#include <optional>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Pillow.hpp"
#include "isohex/pipeline/Contour.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/StageSink.hpp"

namespace isohex::pipeline {

struct PillowResult {
    bool enabled = false;  // settings.pillow; nothing else is set without it
    int layers = 0;
    std::size_t sheets = 0;
    std::size_t hexesAdded = 0;
    std::size_t invertedAtInsertion = 0;
    std::optional<ReturnResult> returned;  // when given held-back vertices (with the pillow or without)
};

// Pillows the mesh unless settings.pillow is off (stage "pillow"); then,
// given the vertices contour held back, takes them back towards their
// targets as far as the hexes allow (returnTowardsTargets). `passes`, when
// given, receives each material's sheet (its copies), for a part's node keys
// (Part.hpp).
PillowResult pillowBoundary(HexMesh& mesh, const MeshSettings& settings, StageSink& sink,
                            std::vector<isohex::PillowResult>* passes = nullptr, const HeldBack* heldBack = nullptr);

}  // namespace isohex::pipeline

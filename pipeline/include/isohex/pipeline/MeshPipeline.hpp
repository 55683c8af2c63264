#pragma once
// The whole meshing pipeline as one call: prepare -> contour -> pillow ->
// optimise -> retries -> fidelity for scans (and surfaces as level sets), or
// the sheet method for surfaces. Writing the files and printing are left to
// the commands.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "isohex/core/HexMesh.hpp"
#include "isohex/pipeline/Fidelity.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/MinQuality.hpp"
#include "isohex/pipeline/Part.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "isohex/pipeline/Pillow.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/Retries.hpp"
#include "isohex/pipeline/StageSink.hpp"

namespace isohex::pipeline {

// What one run of the pipeline on a scan found, stage by stage.
struct MeshReport {
    PreparedFacts prepared;
    Method method = Method::Dual;
    std::size_t contouredHexes = 0, contouredNodes = 0;
    PillowResult pillow;
    OptimizeResult optimization;
    std::optional<RetryResult> retries;  // Method::Dual with optimisation
    std::optional<RelaxationResult> relaxation;  // when hexes stayed below the certified minimum
    FidelityResult fidelity;
    std::vector<std::pair<std::int32_t, std::size_t>> hexesPerMaterial;  // by material
    std::optional<AdaptiveFacts> adaptive;  // settings.adaptive
    std::vector<std::string> warnings;   // preparation's first
    double seconds = 0;
    std::optional<PartFacts> part;       // settings.part
};

struct MeshOutcome {
    HexMesh mesh;
    nlohmann::json report;  // ReportJson.hpp's writing of the run's report ("quality": the certificate)
    // Per-hex fields for the mesh file (.vtu cell data): "level" with --adaptive.
    std::vector<std::pair<std::string, std::vector<double>>> cellFields;
    QualityCertificate quality;  // of `mesh` against --min-quality
    // With settings.part: where the part lies and its nodes' keys, for the
    // part file (addPartArrays).
    std::optional<PartWindow> part;
    std::optional<PartNodes> partNodes;
};

// Meshes `input` by settings.method, with the report of every stage and the
// certificate of the mesh against the minimum quality.
MeshOutcome runMeshPipeline(const std::string& input, const MeshSettings& settings, StageSink& sink);

}  // namespace isohex::pipeline

#pragma once
// The report writer: every stage's result mapped to the JSON report, in one
// place. The report's keys are a public format (scripts read them): add keys,
// never rename one.
#include <nlohmann/json.hpp>

#include "isohex/pipeline/FeatureRemoval.hpp"
#include "isohex/pipeline/Fidelity.hpp"
#include "isohex/pipeline/Merge.hpp"
#include "isohex/pipeline/MeshPipeline.hpp"
#include "isohex/pipeline/MinQuality.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "isohex/pipeline/Pillow.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/Retries.hpp"
#include "isohex/pipeline/SheetMethod.hpp"

namespace isohex::pipeline {

nlohmann::json toJson(const InputFacts& input);          // "input"
nlohmann::json toJson(const SelectionFacts& selection);  // "selection"
nlohmann::json toJson(const GridFacts& grid);            // "grid"
nlohmann::json toJson(const PillowResult& pillow);       // "pillow"
nlohmann::json toJson(const WorstHexPassResult& pass);   // "worst_hexes"
nlohmann::json toJson(const OptimizeResult& opt);        // "optimization"
nlohmann::json toJson(const smoothing::BoundaryQuadResult& r);  // compare's "boundary_quads"
nlohmann::json toJson(const RetryResult& retries);       // "retries"
nlohmann::json toJson(const FidelityResult& fidelity);   // "fidelity"
nlohmann::json toJson(const AdaptiveFacts& adaptive);    // "adaptive"
nlohmann::json toJson(const QualityCertificate& quality);  // "quality"
nlohmann::json toJson(const FeatureRemovalResult& r);     // one of "quality"."means"
nlohmann::json toJson(const PartFacts& part);            // "part"
nlohmann::json toJson(const MergeResult& merge);         // merge's "merge"
// The whole report of a run on a scan, and of the sheet method.
nlohmann::json toJson(const MeshReport& report);
nlohmann::json toJson(const SheetMethodReport& report);

}  // namespace isohex::pipeline

#include "isohex/pipeline/MeshPipeline.hpp"

#include <map>

#include "Stage.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/pipeline/ReportJson.hpp"
#include "isohex/pipeline/SheetMethod.hpp"

namespace isohex::pipeline {

MeshOutcome runMeshPipeline(const std::string& input, const MeshSettings& settings, StageSink& sink) {
    if (settings.method == Method::Sheets) {
        SheetMeshing s = runSheetMethod(input, settings, sink);
        return {std::move(s.mesh), toJson(s.report), {}, {}};
    }
    const Stopwatch clock;
    Meshing m = meshLabels(prepare(input, settings, sink), settings, sink);
    MeshReport r;
    r.method = settings.method;
    std::vector<std::string> warnings;  // after preparation's
    if (settings.optimize) {
        RetryResult retries = retryStuckHexes(m, settings, sink, warnings);
        if (settings.method == Method::Dual) r.retries = std::move(retries);
    }
    r.fidelity = timedStage(sink, "fidelity", [&] { return fidelity(m.mesh, m.prepared); });
    r.prepared = m.prepared.facts;
    r.contouredHexes = m.contouredHexes;
    r.contouredNodes = m.contouredNodes;
    r.pillow = m.pillow;
    r.optimization = m.optimization;
    std::map<std::int32_t, std::size_t> hexes;
    for (auto mat : m.mesh.material) ++hexes[mat];
    r.hexesPerMaterial.assign(hexes.begin(), hexes.end());
    r.warnings = m.prepared.warnings;
    r.warnings.insert(r.warnings.end(), warnings.begin(), warnings.end());
    r.seconds = clock.seconds();
    if (!m.prepared.part) return {std::move(m.mesh), toJson(r), {}, {}};
    r.part = PartFacts{*m.prepared.part, 0};
    for (auto c : m.partNodes->onCut) r.part->cutNodes += c;
    return {std::move(m.mesh), toJson(r), m.prepared.part, std::move(m.partNodes)};
}

}  // namespace isohex::pipeline

#include "isohex/pipeline/MeshPipeline.hpp"

#include <map>

#include "Stage.hpp"
#include "isohex/octree/RepairedDomain.hpp"
#include "isohex/pipeline/FeatureRemoval.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/pipeline/ReportJson.hpp"
#include "isohex/pipeline/SheetMethod.hpp"

namespace isohex::pipeline {

namespace {

// The outcome with its certificate, in the report as "quality".
MeshOutcome certified(MeshOutcome out, const std::string& input, const MeshSettings& settings,
                      const std::optional<RelaxationResult>& relaxation, const LocalFeatures* local = nullptr,
                      const std::optional<FeatureRemovalResult>& features = std::nullopt) {
    out.quality = certifyQuality(out.mesh, minQualityFor(input, settings), local, settings.optimize);
    out.quality.defaultTarget = !settings.minQuality.has_value();
    if (worstHexTargetFor(input, settings) > settings.worstHexTarget.value_or(kDefaultWorstHexTarget) &&
        settings.optimize && settings.worstHexPass)
        out.quality.worstHexTarget = worstHexTargetFor(input, settings);
    out.quality.relaxation = relaxation;
    out.report["quality"] = toJson(out.quality);
    if (features) out.report["quality"]["means"].push_back(toJson(*features));
    return out;
}

}  // namespace

MeshOutcome runMeshPipeline(const std::string& input, const MeshSettings& settings, StageSink& sink) {
    if (settings.method == Method::Sheets) {
        SheetMeshing s = runSheetMethod(input, settings, sink);
        return certified({std::move(s.mesh), toJson(s.report), {}}, input, settings, std::nullopt);
    }
    const Stopwatch clock;
    Meshing m = meshLabels(prepare(input, settings, sink), settings, sink);
    MeshReport r;
    r.method = settings.method;
    std::vector<std::string> warnings;  // after preparation's
    std::optional<FeatureRemovalResult> features;
    if (settings.optimize) {
        RetryResult retries = retryStuckHexes(m, settings, sink);
        r.relaxation = relaxToMinQuality(m.mesh, m.prepared, settings, sink);
        features = removeFineFeatures(m, settings, sink, r.relaxation);
        m.nodeKeys = {};  // nothing meshes again from here on
        warnStuckHexes(m, retries, settings, sink, warnings);
        if (settings.method == Method::Dual) r.retries = std::move(retries);
    }
    // A part's cut nodes stayed frozen through every stage that moves nodes.
    if (m.partNodes) unfreezeCutNodes(m.mesh, *m.partNodes);
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
    std::vector<std::pair<std::string, std::vector<double>>> fields;
    if (m.adaptive) {
        fields.emplace_back("level", std::vector<double>(m.adaptive->hexLevel.begin(), m.adaptive->hexLevel.end()));
        r.adaptive = std::move(m.adaptive);
        r.adaptive->hexLevel.clear();
    }
    MeshOutcome out{std::move(m.mesh), {}, std::move(fields), {}, std::nullopt, std::nullopt};
    if (m.prepared.part) {
        r.part = PartFacts{*m.prepared.part, 0};
        for (auto c : m.partNodes->onCut) r.part->cutNodes += c;
        out.part = m.prepared.part;
        out.partNodes = std::move(m.partNodes);
    }
    out.report = toJson(r);
    // the labels the mesh was contoured from, for the shape next to each hex below Q
    const LocalFeatures local(m.prepared.labels,
                              dynamic_cast<const octree::RepairedDomain*>(m.prepared.repairedDomain.get()));
    return certified(std::move(out), input, settings, r.relaxation, m.prepared.labels.material.empty() ? nullptr : &local,
                     features);
}

}  // namespace isohex::pipeline

#include "isohex/pipeline/Pillow.hpp"

#include "Stage.hpp"
#include "isohex/core/Pillow.hpp"

namespace isohex::pipeline {

PillowResult pillowBoundary(HexMesh& mesh, const MeshSettings& settings, StageSink& sink,
                            std::vector<isohex::PillowResult>* passes) {
    PillowResult r;
    r.enabled = settings.pillow;
    if (!settings.pillow) return r;
    Stage st(sink, "pillow");
    const std::size_t before = mesh.hexCount();
    PillowOptions opt;
    const auto results = pillowAllMaterials(mesh, settings.boundaryLayers, opt);
    r.layers = settings.boundaryLayers;
    r.sheets = results.size();
    r.hexesAdded = mesh.hexCount() - before;
    for (const auto& s : results) r.invertedAtInsertion += s.invertedAtStart;
    if (passes) *passes = results;
    st.finish();
    return r;
}

}  // namespace isohex::pipeline

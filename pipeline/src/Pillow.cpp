#include "isohex/pipeline/Pillow.hpp"

#include "Stage.hpp"
#include "isohex/core/Pillow.hpp"

namespace isohex::pipeline {

PillowResult pillowBoundary(HexMesh& mesh, const MeshSettings& settings, StageSink& sink,
                            std::vector<isohex::PillowResult>* passes, const HeldBack* heldBack) {
    PillowResult r;
    r.enabled = settings.pillow;
    if (!settings.pillow) {
        if (heldBack) r.returned = returnTowardsTargets(mesh, *heldBack);
        return r;
    }
    Stage st(sink, "pillow");
    const std::size_t before = mesh.hexCount();
    PillowOptions opt;
    const auto results = pillowAllMaterials(mesh, settings.boundaryLayers, opt);
    r.layers = settings.boundaryLayers;
    r.sheets = results.size();
    r.hexesAdded = mesh.hexCount() - before;
    for (const auto& s : results) r.invertedAtInsertion += s.invertedAtStart;
    if (passes) *passes = results;
    if (heldBack) r.returned = returnTowardsTargets(mesh, *heldBack);
    st.finish();
    return r;
}

}  // namespace isohex::pipeline

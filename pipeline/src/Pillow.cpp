#include "isohex/pipeline/Pillow.hpp"

#include <algorithm>

#include "Stage.hpp"
#include "isohex/core/NodeTargets.hpp"
#include "isohex/core/Pillow.hpp"

namespace isohex::pipeline {

namespace {

// The held-back vertices return towards their targets (returnTowardsTargets);
// then the sheet's copies of those that moved follow them by the same
// displacement, as far as the hexes allow. The copies were placed a step
// inside from the held-back positions: left there, a surface vertex that
// returns past its copy leaves the sheet hexes around it folded flat, a
// trap the optimiser does not leave (ch2bet at 4 mm: three hexes at 0.08
// where the copies follow and end at 0.43).
ReturnResult returnWithCopies(HexMesh& mesh, const HeldBack& heldBack,
                              const std::vector<isohex::PillowResult>& passes) {
    std::vector<Vec3> before(heldBack.nodes.size());
    for (std::size_t i = 0; i < before.size(); ++i) before[i] = mesh.nodes[static_cast<std::size_t>(heldBack.nodes[i])];
    ReturnResult r = returnTowardsTargets(mesh, heldBack);
    std::vector<Index> copies;
    std::vector<Vec3> targets;
    for (const isohex::PillowResult& p : passes)
        for (std::size_t j = 0; j < p.copyOf.size(); ++j) {
            const auto it = std::lower_bound(heldBack.nodes.begin(), heldBack.nodes.end(), p.copyOf[j]);
            if (it == heldBack.nodes.end() || *it != p.copyOf[j]) continue;
            const auto i = static_cast<std::size_t>(it - heldBack.nodes.begin());
            const Vec3& now = mesh.nodes[static_cast<std::size_t>(*it)];
            if (now == before[i]) continue;
            const Index c = p.firstNewNode + static_cast<Index>(j);
            const Vec3& x = mesh.nodes[static_cast<std::size_t>(c)];
            copies.push_back(c);
            targets.push_back({x[0] + now[0] - before[i][0], x[1] + now[1] - before[i][1], x[2] + now[2] - before[i][2]});
        }
    r.copiesFollowed = moveTowardsTargets(mesh, copies, targets);
    return r;
}

}  // namespace

PillowResult pillowBoundary(HexMesh& mesh, const MeshSettings& settings, StageSink& sink,
                            std::vector<isohex::PillowResult>* passes, const HeldBack* heldBack) {
    PillowResult r;
    r.enabled = settings.pillow;
    if (settings.tangledStart) heldBack = nullptr;  // held-back vertices stay for the optimiser
    if (!settings.pillow) {
        if (heldBack) r.returned = returnTowardsTargets(mesh, *heldBack);
        return r;
    }
    Stage st(sink, "pillow");
    const std::size_t before = mesh.hexCount();
    PillowOptions opt;
    opt.turnIntoCorners = !settings.tangledStart;
    opt.stepOnAlone = !settings.tangledStart;
    const auto results = pillowAllMaterials(mesh, settings.boundaryLayers, opt);
    r.layers = settings.boundaryLayers;
    r.sheets = results.size();
    r.hexesAdded = mesh.hexCount() - before;
    for (const auto& s : results) r.invertedAtInsertion += s.invertedAtStart;
    if (heldBack) r.returned = returnWithCopies(mesh, *heldBack, results);
    if (passes) *passes = results;
    st.finish();
    return r;
}

}  // namespace isohex::pipeline

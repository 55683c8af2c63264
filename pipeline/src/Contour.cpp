#include "isohex/pipeline/Contour.hpp"

#include <string>

#include "Stage.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/octree/DualContour.hpp"

namespace isohex::pipeline {

HexMesh contour(const Prepared& p, const MeshSettings& settings, StageSink& sink) {
    return contour(p, settings, sink, nullptr);
}

HexMesh contour(const Prepared& p, const MeshSettings& settings, StageSink& sink, AdaptiveFacts* adaptive,
                HeldBack* heldBack) {
    Stage st(sink, "extract");
    octree::ExtractOptions opt;
    opt.meshExterior = settings.meshExterior;
    opt.validStart = !settings.tangledStart;
    if (settings.method == Method::Voxel) opt.cellCentres = true;
    else if (settings.method != Method::Dual)
        throw SettingError({Setting::Method, " must be 'dual' or 'voxel' (got '" +
                                                 std::string(methodName(settings.method)) + "')"});
    octree::ExtractStats stats;
    HexMesh mesh = octree::dualContourHexes(p.labels, p.extractionDomain(), opt, &stats);
    // The sheet is placed on the valid mesh of the held-back positions:
    // placed with the surface vertices on the surface, its copies start
    // against folded surface quads, and those sheet hexes inverted.
    if (heldBack) {
        heldBack->nodes = stats.heldBack;
        heldBack->targets.resize(stats.heldBack.size());
    }
    for (std::size_t i = 0; i < stats.heldBack.size(); ++i) {
        const auto v = static_cast<std::size_t>(stats.heldBack[i]);
        if (heldBack) heldBack->targets[i] = mesh.nodes[v];
        mesh.nodes[v] = stats.heldBackAt[i];
    }
    if (settings.meshExterior)  // the box around the exterior does not move
        for (std::size_t s = 0; s < mesh.surfaces.size(); ++s)
            if (mesh.surfaces[s].inside <= 0 && mesh.surfaces[s].outside <= 0)
                for (auto& c : mesh.nodeClass)
                    if (c.kind == NodeKind::Surface && c.id == static_cast<std::int32_t>(s)) c = {NodeKind::Fixed, -1};
    if (settings.adaptive) {
        if (!adaptive) throw Error("internal error: adaptive contouring without a place for its facts");
        if (settings.method != Method::Dual || settings.meshExterior)
            throw SettingError({Setting::Method, " must be 'dual' without meshing the exterior for the adaptive mesher"});
        HexMesh tree = coarsenContour(p, mesh, settings, *adaptive);
        if (keepTree(tree, mesh, settings, *adaptive)) {
            mesh = std::move(tree);
            if (heldBack) *heldBack = {};  // the coarsened mesh numbers its nodes anew
        }
    }
    st.finish();
    return mesh;
}

ReturnResult returnTowardsTargets(HexMesh& mesh, const HeldBack& heldBack) {
    const Stopwatch clock;
    ReturnResult r;
    r.heldBack = heldBack.nodes.size();
    r.moved = moveTowardsTargets(mesh, heldBack.nodes, heldBack.targets);
    r.seconds = clock.seconds();
    return r;
}

}  // namespace isohex::pipeline

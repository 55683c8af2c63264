#include "isohex/pipeline/Contour.hpp"

#include <string>

#include "Stage.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"
#include "isohex/octree/DualContour.hpp"

namespace isohex::pipeline {

HexMesh contour(const Prepared& p, const MeshSettings& settings, StageSink& sink) {
    return contour(p, settings, sink, nullptr);
}

HexMesh contour(const Prepared& p, const MeshSettings& settings, StageSink& sink, AdaptiveFacts* adaptive) {
    Stage st(sink, "extract");
    octree::ExtractOptions opt;
    opt.meshExterior = settings.meshExterior;
    if (settings.method == Method::Voxel) opt.cellCentres = true;
    else if (settings.method != Method::Dual)
        throw SettingError({Setting::Method, " must be 'dual' or 'voxel' (got '" +
                                                 std::string(methodName(settings.method)) + "')"});
    octree::ExtractStats stats;
    HexMesh mesh = octree::dualContourHexes(p.labels, p.extractionDomain(), opt, &stats);
    // Starting the sheet's inner copies at the held-back positions with the
    // surface nodes on the surface does worse: the surface quads of those
    // nodes are folded, so the sheet hexes on them start inverted (more
    // inverted at insertion, and some left after optimisation).
    for (std::size_t i = 0; i < stats.heldBack.size(); ++i)
        mesh.nodes[static_cast<std::size_t>(stats.heldBack[i])] = stats.heldBackAt[i];
    if (settings.meshExterior)  // the box around the exterior does not move
        for (std::size_t s = 0; s < mesh.surfaces.size(); ++s)
            if (mesh.surfaces[s].inside <= 0 && mesh.surfaces[s].outside <= 0)
                for (auto& c : mesh.nodeClass)
                    if (c.kind == NodeKind::Surface && c.id == static_cast<std::int32_t>(s)) c = {NodeKind::Fixed, -1};
    if (settings.adaptive) {
        if (!adaptive) throw Error("internal error: adaptive contouring without a place for its facts");
        if (settings.method != Method::Dual || settings.meshExterior)
            throw SettingError({Setting::Method, " must be 'dual' without meshing the exterior for the adaptive mesher"});
        mesh = coarsenContour(p, std::move(mesh), settings, *adaptive);
    }
    st.finish();
    return mesh;
}

}  // namespace isohex::pipeline

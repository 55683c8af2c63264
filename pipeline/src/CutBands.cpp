#include "isohex/pipeline/CutBands.hpp"

#include <algorithm>
#include <utility>

#include "isohex/core/NodeRings.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "isohex/insertion/SheetGeometry.hpp"
#include "isohex/smoothing/Optimize.hpp"
#include "isohex/smoothing/WorstHexes.hpp"

namespace isohex::pipeline {

namespace {

// The hexes touching a band node as a mesh of their own; `from` gives each
// of its nodes' index in `mesh`.
HexMesh bandMesh(const HexMesh& mesh, const std::vector<std::uint8_t>& band, std::vector<Index>& from) {
    HexMesh sub;
    sub.surfaces = mesh.surfaces;
    sub.curves = mesh.curves;
    std::vector<Index> to(mesh.nodeCount(), kNone);
    for (std::size_t h = 0; h < mesh.hexCount(); ++h) {
        const Hex& hex = mesh.hexes[h];
        if (std::none_of(hex.begin(), hex.end(), [&](Index v) { return band[static_cast<std::size_t>(v)] != 0; }))
            continue;
        Hex local{};
        for (int k = 0; k < 8; ++k) {
            const auto v = static_cast<std::size_t>(hex[k]);
            if (to[v] == kNone) {
                to[v] = sub.addNode(mesh.nodes[v], mesh.nodeClass[v]);
                from.push_back(hex[k]);
            }
            local[k] = to[v];
        }
        sub.addHex(local, mesh.material[h]);
    }
    return sub;
}

// The scaled Jacobian below which a hex seeds the band: the worst-hex
// target, or the second target where the parts reached the first away from
// their cuts (they ran the second pass then; elsewhere the band stays as
// small as without it).
double seedTarget(const HexMesh& mesh, const std::vector<std::uint8_t>& onCut, const std::vector<double>& sj,
                  const CutBandScan* scan) {
    const double target = smoothing::WorstHexOptions{}.target;
    if (!scan || !(scan->stretchTarget > target)) return target;
    for (std::size_t h = 0; h < mesh.hexCount(); ++h) {
        bool atCut = false;
        for (Index v : mesh.hexes[h]) atCut = atCut || onCut[static_cast<std::size_t>(v)];
        if (!atCut && !(sj[h] >= target)) return target;
    }
    return scan->stretchTarget;
}

}  // namespace

CutBandResult optimiseCutBands(HexMesh& mesh, const std::vector<std::uint8_t>& onCut, const CutBandScan* scan,
                               int rings) {
    const Stopwatch clock;
    CutBandResult r;
    // Seeds: the cut nodes and the nodes of every hex below the worst-hex
    // target, wherever it is (a part's max-min pass leaves hexes far from
    // its cuts lower than the single run does).
    std::vector<std::uint8_t> seeds = onCut;
    const std::vector<double> sj = scaledJacobians(mesh);
    const double target = seedTarget(mesh, onCut, sj, scan);
    for (std::size_t h = 0; h < mesh.hexCount(); ++h)
        if (!(sj[h] >= target) || scaledJacobianCollapsed(sj[h]))
            for (Index v : mesh.hexes[h]) seeds[static_cast<std::size_t>(v)] = 1;
    const std::vector<std::uint8_t> band = nodesWithinRings(mesh, std::move(seeds), rings);  // the nodes that move
    std::vector<Index> from;
    HexMesh sub = bandMesh(mesh, band, from);
    r.hexes = sub.hexCount();
    if (sub.hexCount() == 0) return r;
    const QualitySummary before = summarize(sub, computeQuality(sub));
    r.minBefore = before.scaledJacobian.min;
    r.invertedBefore = before.inverted;
    // The band's surfaces: the scan's isosurface, or else its boundary quads
    // in triangle trees (the band's own edge, inside the merged mesh, is
    // fixed below). The band keeps the merged mesh's surface and curve ids,
    // which the scan's projector was made with.
    insertion::SheetGeometry geometry;
    const smoothing::SurfaceProjector* projector = &geometry;
    smoothing::WorstHexOptions worst;
    if (scan) {
        projector = scan->projector;
        worst.surfaceSlack = scan->surfaceSlack;
    } else {
        insertion::adoptBoundary(sub, geometry, kCutBandFeatureAngle);
    }
    for (std::size_t v = 0; v < sub.nodeCount(); ++v) {
        if (!band[static_cast<std::size_t>(from[v])]) sub.nodeClass[v] = {NodeKind::Fixed, -1};
        else ++r.nodes;
    }
    smoothing::optimizeMesh(sub, projector, smoothing::SmoothingOptions{});
    const smoothing::WorstHexResult raised = smoothing::raiseWorstHexes(sub, projector, worst);
    if (scan) stretchIfReached(sub, projector, worst.target, raised.minAfter, scan->stretchTarget, worst.surfaceSlack);
    const QualitySummary after = summarize(sub, computeQuality(sub));
    r.minAfter = after.scaledJacobian.min;
    r.invertedAfter = after.inverted;
    // Kept unless it inverts more hexes or lowers the minimum below the
    // smaller of the band's minimum before and the worst-hex target (the
    // max-min pass's own promise: with the scan it may trade a little of a
    // minimum above the target for boundary nodes back on the isosurface).
    const double floor = std::min(before.scaledJacobian.min, worst.target);
    r.kept = after.inverted < before.inverted ||
             (after.inverted == before.inverted && after.scaledJacobian.min >= floor);
    if (r.kept)
        for (std::size_t v = 0; v < sub.nodeCount(); ++v)
            if (band[static_cast<std::size_t>(from[v])]) mesh.nodes[static_cast<std::size_t>(from[v])] = sub.nodes[v];
    r.seconds = clock.seconds();
    return r;
}

}  // namespace isohex::pipeline

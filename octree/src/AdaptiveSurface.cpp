#include "isohex/octree/AdaptiveSurface.hpp"

#include <algorithm>

#include "AdaptiveSurfaceParts.hpp"

namespace isohex::octree {

namespace {

// Asks for the leaf at `h` to be refined; whether that is new.
bool request(RequestMasks& req, const RefinementTree& tree, const Leaf& leaf) {
    if (leaf.level < 1) return false;
    const RefinementLevel& L = tree.levels[static_cast<std::size_t>(leaf.level)];
    std::uint8_t& r = req[static_cast<std::size_t>(leaf.level)][L.index(leaf.cell[0], leaf.cell[1], leaf.cell[2])];
    if (r) return false;
    r = 1;
    return true;
}

// Turns the problems into requests for the leaves around their nodes and
// the leaves of their hexes, in reason and index order. Returns the round's
// new requests; `unfixable` counts problems with no coarse leaf to refine.
AdaptiveRound requestRefinement(const PlacedMesh& p, const Problems& problems, const LeafLocator& locate,
                                const RefinementTree& tree, RequestMasks& req, std::size_t& unfixable) {
    AdaptiveRound round;
    const auto& keys = p.a.nodeKeys;
    for (int r = 0; r < kRefineReasons; ++r) {
        std::size_t& added = round.cells[static_cast<std::size_t>(r)];
        for (Index n : problems.nodes[static_cast<std::size_t>(r)]) {
            const auto q = keyCoords(keys[static_cast<std::size_t>(n)]);
            bool coarse = false;
            for (int c = 0; c < 8; ++c) {
                const HalfKey h{2 * q[0] + ((c & 1) ? 1 : -1), 2 * q[1] + ((c & 2) ? 1 : -1), 2 * q[2] + ((c & 4) ? 1 : -1)};
                const Leaf leaf = locate.at(h);
                coarse = coarse || leaf.level >= 1;
                added += request(req, tree, leaf);
            }
            unfixable += !coarse;
        }
        for (Index hx : problems.hexes[static_cast<std::size_t>(r)]) {
            HalfKey sum{0, 0, 0};
            for (Index n : p.a.mesh.hexes[static_cast<std::size_t>(hx)]) {
                const auto q = keyCoords(keys[static_cast<std::size_t>(n)]);
                for (int c = 0; c < 3; ++c) sum[c] += q[c];
            }
            added += request(req, tree, locate.at({sum[0] / 4, sum[1] / 4, sum[2] / 4}));
        }
    }
    return round;
}

}  // namespace

AdaptiveSurfaceResult contourAdaptive(const Labels& labels, const Domain& domain, const HexMesh& uniform,
                                      const AdaptiveSurfaceSettings& settings, const RequestMasks& extra) {
    AdaptiveSurfaceResult out;
    const auto points = labels.grid.dims;
    const int top = topLevelFor(points, settings.maxLevel);
    RequestMasks req = surfaceRequests(labels, top);
    out.criterionCells.assign(static_cast<std::size_t>(top) + 1, 0);
    for (std::size_t l = 1; l < req.size(); ++l)
        out.criterionCells[l] = static_cast<std::size_t>(std::count(req[l].begin(), req[l].end(), 1));
    orRequests(req, extra);
    const UniformNodes uniformAt(labels, uniform);
    const auto sp = labels.grid.spacing();
    const double tolerance = settings.deviation * std::max({sp[0], sp[1], sp[2]});
    for (int round = 0;; ++round) {
        out.tree = closeRefinement(points, top, req, settings.grading);
        const LeafLocator locate(out.tree);
        PlacedMesh p = placeAdaptive(leafHexes(out.tree, labels), locate, labels, uniformAt, uniform, domain);
        const Problems problems = findProblems(p, domain, tolerance);
        std::size_t unfixable = 0;
        const AdaptiveRound r = requestRefinement(p, problems, locate, out.tree, req, unfixable);
        std::size_t added = 0;
        for (std::size_t c : r.cells) added += c;
        if (added == 0 || round == settings.maxRounds) {
            out.unresolved = unfixable;
            if (added) {
                for (const auto& list : problems.nodes) out.unresolved += list.size();
            }
            out.mesh = std::move(p.a);
            return out;
        }
        out.rounds.push_back(r);
    }
}

}  // namespace isohex::octree

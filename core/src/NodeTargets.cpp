#include "isohex/core/NodeTargets.hpp"

#include <string>
#include <vector>

#include "isohex/core/Error.hpp"
#include "isohex/core/Parallel.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex {

namespace {

// Whether every hex of `row` that was valid stays valid with node v at x.
bool keepsValid(HexMesh& mesh, const Index* begin, const Index* end, const std::vector<std::uint8_t>& judged,
                std::size_t v, const Vec3& x) {
    const Vec3 old = mesh.nodes[v];
    mesh.nodes[v] = x;
    bool ok = true;
    for (const Index* h = begin; h != end && ok; ++h)
        ok = !judged[static_cast<std::size_t>(h - begin)] || minJacobianDeterminant(hexCoords(mesh, *h)) > 0;
    mesh.nodes[v] = old;
    return ok;
}

}  // namespace

TargetsResult moveTowardsTargets(HexMesh& mesh, std::span<const Index> nodes, std::span<const Vec3> targets,
                                 int halvings, int passes) {
    using namespace vec;
    if (nodes.size() != targets.size())
        throw Error("moveTowardsTargets: " + std::to_string(nodes.size()) + " nodes but " +
                    std::to_string(targets.size()) + " targets");
    const std::size_t N = mesh.nodeCount(), K = nodes.size();
    std::vector<Index> slot(N, kNone);
    for (std::size_t i = 0; i < K; ++i) {
        const Index v = nodes[i];
        if (v < 0 || static_cast<std::size_t>(v) >= N)
            throw Error("moveTowardsTargets: node " + std::to_string(v) + " but the mesh has " + std::to_string(N) +
                        " nodes");
        slot[static_cast<std::size_t>(v)] = static_cast<Index>(i);
    }
    const BigCsr around = parallel::rowsInOrder(K, mesh.hexCount(), [&](std::size_t lo, std::size_t hi, auto emit) {
        for (std::size_t h = lo; h < hi; ++h)
            for (Index v : mesh.hexes[h])
                if (const Index s = slot[static_cast<std::size_t>(v)]; s != kNone) emit(s, static_cast<Index>(h));
    });
    TargetsResult r;
    std::vector<std::uint8_t> moved(K, 0), done(K, 0), judged;
    for (int pass = 0; pass < passes; ++pass) {
        bool any = false;
        for (std::size_t i = 0; i < K; ++i) {
            if (done[i]) continue;
            const auto v = static_cast<std::size_t>(nodes[i]);
            const Index* b = around.begin(i);
            const Index* e = around.end(i);
            judged.resize(static_cast<std::size_t>(e - b));
            for (const Index* h = b; h != e; ++h)
                judged[static_cast<std::size_t>(h - b)] = minJacobianDeterminant(hexCoords(mesh, *h)) > 0;
            const Vec3 x = mesh.nodes[v];
            const Vec3 way = targets[i] - x;
            double t = 1.0;
            for (int k = 0; k <= halvings; ++k, t *= 0.5) {
                const Vec3 y = k == 0 ? targets[i] : x + t * way;
                if (!keepsValid(mesh, b, e, judged, v, y)) continue;
                mesh.nodes[v] = y;
                moved[i] = 1;
                done[i] = k == 0;
                any = true;
                break;
            }
        }
        if (!any) break;
    }
    for (std::size_t i = 0; i < K; ++i) {
        if (done[i]) ++r.reached;
        else if (moved[i]) ++r.partway;
        else ++r.stayed;
    }
    return r;
}

}  // namespace isohex

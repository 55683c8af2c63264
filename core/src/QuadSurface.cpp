#include "isohex/core/QuadSurface.hpp"

#include <algorithm>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Parallel.hpp"

namespace isohex {

ManifoldCheck checkManifold(const std::vector<std::array<Index, 4>>& quads, std::size_t nodeCount, bool closed) {
    // node -> (quad, corner) items
    const Csr around = parallel::bucketItems(nodeCount, quads.size() * 4,
                                             [&](std::size_t i) { return quads[i / 4][i % 4]; });
    return checkManifold(quads.data(), around.offsets.data(), around.items.data(), nodeCount, closed);
}

ManifoldCheck checkManifold(const std::array<Index, 4>* quads, const Index* rowOffsets, const Index* rowItems,
                            std::size_t nodeCount, bool closed) {
    std::vector<std::uint8_t> nodeBad(nodeCount, 0);
    ManifoldCheck out;
    using Edge = std::array<Index, 2>;
    out.badEdges = parallel::collectSorted<Edge>(nodeCount, 256, [&](const auto& r, std::vector<Edge>& bad) {
        // (neighbour node, local quad slot) pairs and a tiny union-find over the quads at v
        std::vector<std::pair<Index, Index>> spokes;
        DisjointSets<Index> fans;
        for (std::size_t v = r.begin(); v != r.end(); ++v) {
            const std::size_t n = static_cast<std::size_t>(rowOffsets[v + 1] - rowOffsets[v]);
            if (n == 0) continue;
            spokes.clear();
            fans.reset(n);
            for (std::size_t s = 0; s < n; ++s) {
                const Index item = rowItems[rowOffsets[v] + static_cast<Index>(s)];
                const auto& q = quads[item / 4];
                const int c = item % 4;
                spokes.emplace_back(q[(c + 1) % 4], static_cast<Index>(s));
                spokes.emplace_back(q[(c + 3) % 4], static_cast<Index>(s));
            }
            std::sort(spokes.begin(), spokes.end());
            for (std::size_t i = 0; i < spokes.size();) {
                std::size_t j = i;
                while (j < spokes.size() && spokes[j].first == spokes[i].first) ++j;
                const std::size_t uses = j - i;
                const Index w = spokes[i].first;
                if (uses > 2 || (closed && uses == 1)) {
                    if (static_cast<Index>(v) < w) bad.push_back({static_cast<Index>(v), w});
                } else if (uses == 2) {
                    fans.unite(spokes[i].second, spokes[i + 1].second);
                }
                i = j;
            }
            if (fans.countSets() > 1) nodeBad[v] = 1;
        }
    });
    for (std::size_t v = 0; v < nodeCount; ++v)
        if (nodeBad[v]) out.badNodes.push_back(static_cast<Index>(v));
    return out;
}

}  // namespace isohex

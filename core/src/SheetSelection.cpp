#include "isohex/core/SheetSelection.hpp"

#include <algorithm>
#include <random>
#include <string>

#include "isohex/core/Error.hpp"

namespace isohex {

Index sheetThroughEdge(const HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index a, Index b) {
    const Index e = edgeBetween(mesh, topo, a, b);
    if (e == kNone) throw Error("no mesh edge joins nodes " + std::to_string(a) + " and " + std::to_string(b));
    return sheets.edgeSheet[static_cast<std::size_t>(e)];
}

std::vector<Index> sheetsTouchingSurfaces(const Topology& topo, const DualSheets& sheets) {
    std::vector<std::uint8_t> touch(sheets.count(), 0);
    for (std::size_t e = 0; e < topo.edges.size(); ++e)
        if (topo.nodeOnBoundary[topo.edges[e][0]] || topo.nodeOnBoundary[topo.edges[e][1]]) touch[sheets.edgeSheet[e]] = 1;
    std::vector<Index> out;
    for (std::size_t s = 0; s < touch.size(); ++s)
        if (touch[s]) out.push_back(static_cast<Index>(s));
    return out;
}

std::vector<Index> fundamentalSheets(const HexMesh& mesh, const Topology& topo, const DualSheets& sheets) {
    std::vector<std::uint8_t> onSurface(mesh.nodeCount(), 0);
    for (Index v : topo.boundaryNodes) onSurface[v] = 1;
    for (Index q : topo.interfaceQuads)
        for (Index v : topo.quads[q].nodes) onSurface[v] = 1;
    std::vector<Index> out;
    for (std::size_t s = 0; s < sheets.count(); ++s) {
        bool ok = true;
        for (const Index* e = sheets.sheetEdges.begin(s); ok && e != sheets.sheetEdges.end(s); ++e)
            ok = onSurface[topo.edges[*e][0]] != onSurface[topo.edges[*e][1]];
        if (ok) out.push_back(static_cast<Index>(s));
    }
    return out;
}

std::vector<Index> randomSheets(const DualSheets& sheets, std::size_t count, std::uint64_t seed,
                                const std::vector<Index>& exclude) {
    std::vector<std::uint8_t> skip(sheets.count(), 0);
    for (Index s : exclude)
        if (s >= 0 && static_cast<std::size_t>(s) < skip.size()) skip[s] = 1;
    std::vector<Index> pool;
    for (std::size_t s = 0; s < sheets.count(); ++s)
        if (!skip[s]) pool.push_back(static_cast<Index>(s));
    std::mt19937_64 rng(seed);
    // Fisher-Yates with our own index draw, so the sequence is the same on every platform.
    for (std::size_t i = 0; i < pool.size() && i < count; ++i) {
        const std::size_t j = i + static_cast<std::size_t>(rng() % (pool.size() - i));
        std::swap(pool[i], pool[j]);
    }
    pool.resize(std::min(count, pool.size()));
    return pool;
}

}  // namespace isohex

#include "isohex/core/Dual.hpp"

#include <algorithm>

#include "Parallel.hpp"
#include "isohex/core/DisjointSets.hpp"

namespace isohex {

namespace {

// Numbers the classes of a union-find by their smallest member (the root), in order.
std::vector<Index> numberClasses(DisjointSets<Index>& uf, std::size_t n, std::size_t& classes) {
    std::vector<Index> cls(n, kNone);
    Index next = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const Index root = uf.find(static_cast<Index>(i));
        if (root == static_cast<Index>(i)) cls[i] = next++;
        else cls[i] = cls[root];  // root < i, already numbered
    }
    classes = static_cast<std::size_t>(next);
    return cls;
}

// Rows of hexes per class, from per-hex triples of class ids; each row sorted
// and free of repeats (a self-intersecting sheet meets a hex twice).
Csr hexesPerClass(const std::vector<std::array<Index, 3>>& hexClass, std::size_t classes) {
    Csr c = detail::bucketItems(classes, hexClass.size() * 3,
                                [&](std::size_t i) { return hexClass[i / 3][i % 3]; });
    Csr out;
    out.offsets.assign(classes + 1, 0);
    out.items.reserve(c.items.size());
    for (std::size_t r = 0; r < classes; ++r) {
        Index last = kNone;
        for (const Index* p = c.begin(r); p != c.end(r); ++p) {
            const Index h = *p / 3;
            if (h != last) out.items.push_back(h);
            last = h;
        }
        out.offsets[r + 1] = static_cast<Index>(out.items.size());
    }
    return out;
}

}  // namespace

DualSheets buildSheets(const HexMesh& mesh, const Topology& topo) {
    const std::size_t H = mesh.hexes.size();
    DisjointSets<Index> uf(topo.edges.size());
    for (std::size_t h = 0; h < H; ++h)
        for (int d = 0; d < 3; ++d)
            for (int k = 1; k < 4; ++k) uf.unite(topo.hexEdges[h][4 * d], topo.hexEdges[h][4 * d + k]);
    DualSheets s;
    std::size_t count = 0;
    s.edgeSheet = numberClasses(uf, topo.edges.size(), count);
    s.sheetEdges = detail::bucketItems(count, topo.edges.size(), [&](std::size_t e) { return s.edgeSheet[e]; });
    s.hexSheets.resize(H);
    for (std::size_t h = 0; h < H; ++h)
        for (int d = 0; d < 3; ++d) s.hexSheets[h][d] = s.edgeSheet[topo.hexEdges[h][4 * d]];
    s.sheetHexes = hexesPerClass(s.hexSheets, count);
    return s;
}

DualChords buildChords(const HexMesh& mesh, const Topology& topo) {
    const std::size_t H = mesh.hexes.size();
    DisjointSets<Index> uf(topo.quads.size());
    for (std::size_t h = 0; h < H; ++h)
        for (int d = 0; d < 3; ++d) uf.unite(topo.hexQuads[h][2 * d], topo.hexQuads[h][2 * d + 1]);
    DualChords c;
    std::size_t count = 0;
    c.quadChord = numberClasses(uf, topo.quads.size(), count);
    c.chordQuads = detail::bucketItems(count, topo.quads.size(), [&](std::size_t q) { return c.quadChord[q]; });
    c.hexChords.resize(H);
    for (std::size_t h = 0; h < H; ++h)
        for (int d = 0; d < 3; ++d) c.hexChords[h][d] = c.quadChord[topo.hexQuads[h][2 * d]];
    c.chordHexes = hexesPerClass(c.hexChords, count);
    return c;
}

}  // namespace isohex

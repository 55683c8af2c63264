#include "isohex/core/Dual.hpp"

#include <algorithm>
#include <array>
#include <utility>

#include "isohex/core/Parallel.hpp"
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
    Csr c = parallel::bucketItems(classes, hexClass.size() * 3,
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

// The classes of `items` dual items (edges or quads) that link(h, uf) joins
// hex by hex, numbered by their smallest item, with each class's items and
// hexes; itemOf(h, d) is the item of hex h in direction d, which names the
// class that crosses the hex that way.
template <class Link, class ItemOf>
void dualClasses(std::size_t hexes, std::size_t items, Link link, ItemOf itemOf, std::vector<Index>& itemClass,
                 Csr& classItems, std::vector<std::array<Index, 3>>& hexClasses, Csr& classHexes) {
    DisjointSets<Index> uf(items);
    for (std::size_t h = 0; h < hexes; ++h) link(h, uf);
    std::size_t count = 0;
    itemClass = numberClasses(uf, items, count);
    classItems = parallel::bucketItems(count, items, [&](std::size_t i) { return itemClass[i]; });
    hexClasses.resize(hexes);
    for (std::size_t h = 0; h < hexes; ++h)
        for (int d = 0; d < 3; ++d) hexClasses[h][d] = itemClass[itemOf(h, d)];
    classHexes = hexesPerClass(hexClasses, count);
}

}  // namespace

DualSheets buildSheets(const HexMesh& mesh, const Topology& topo) {
    // The four parallel edges of a hex in each direction lie in one sheet.
    DualSheets s;
    dualClasses(
        mesh.hexes.size(), topo.edges.size(),
        [&](std::size_t h, DisjointSets<Index>& uf) {
            for (int d = 0; d < 3; ++d)
                for (int k = 1; k < 4; ++k) uf.unite(topo.hexEdges[h][4 * d], topo.hexEdges[h][4 * d + k]);
        },
        [&](std::size_t h, int d) { return topo.hexEdges[h][4 * d]; }, s.edgeSheet, s.sheetEdges, s.hexSheets,
        s.sheetHexes);
    return s;
}

DualChords buildChords(const HexMesh& mesh, const Topology& topo) {
    // The two opposite faces of a hex in each direction lie in one chord.
    DualChords c;
    dualClasses(
        mesh.hexes.size(), topo.quads.size(),
        [&](std::size_t h, DisjointSets<Index>& uf) {
            for (int d = 0; d < 3; ++d) uf.unite(topo.hexQuads[h][2 * d], topo.hexQuads[h][2 * d + 1]);
        },
        [&](std::size_t h, int d) { return topo.hexQuads[h][2 * d]; }, c.quadChord, c.chordQuads, c.hexChords,
        c.chordHexes);
    return c;
}

}  // namespace isohex

#include "isohex/core/Dice.hpp"

#include <string>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "SurfaceEdges.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex {

namespace {

using namespace vec;

// Reference coordinates of the VTK hex corners.
constexpr int kRef[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

int cornerAt(int x, int y, int z) {
    for (int c = 0; c < 8; ++c)
        if (kRef[c][0] == x && kRef[c][1] == y && kRef[c][2] == z) return c;
    return -1;
}

// The hexes of the sheet, each with the direction (0..2) the sheet crosses it
// in; throws if the sheet crosses a hex twice.
std::vector<std::pair<Index, int>> sheetHexDirections(const DualSheets& sheets, Index sheet) {
    std::vector<std::pair<Index, int>> hexDir;
    for (const Index* h = sheets.sheetHexes.begin(sheet); h != sheets.sheetHexes.end(sheet); ++h) {
        int dir = -1;
        for (int d = 0; d < 3; ++d)
            if (sheets.hexSheets[*h][d] == sheet) {
                if (dir >= 0)
                    throw Error("dice: sheet " + std::to_string(sheet) + " crosses itself in hex " +
                                std::to_string(*h) + "; dicing a self-intersecting sheet is not supported");
                dir = d;
            }
        hexDir.emplace_back(*h, dir);
    }
    return hexDir;
}

// Appends k evenly spaced nodes on each sheet edge, from its first (smaller)
// node to its second; a node on an edge in a surface takes that surface's
// class. Returns, per edge, the first of its new nodes (kNone off the sheet).
std::vector<Index> addEdgeNodes(HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet, int k) {
    const std::vector<std::uint8_t> edgeOnSurface = detail::surfaceEdgeMask(topo);
    const std::size_t N = mesh.nodeCount();
    std::vector<Index> base(topo.edges.size(), kNone);
    Index next = static_cast<Index>(N);
    for (const Index* e = sheets.sheetEdges.begin(sheet); e != sheets.sheetEdges.end(sheet); ++e) {
        base[*e] = next;
        next += k;
    }
    mesh.nodes.resize(static_cast<std::size_t>(next));
    mesh.nodeClass.resize(static_cast<std::size_t>(next));
    const std::size_t E = sheets.sheetEdges.size(sheet);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, E, 256), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const Index e = sheets.sheetEdges.begin(sheet)[i];
            const auto [a, b] = topo.edges[e];
            const NodeClass ca = mesh.nodeClass[a], cb = mesh.nodeClass[b];
            NodeClass c{};
            if (edgeOnSurface[e]) {
                if (ca == cb && ca.kind != NodeKind::Fixed) c = ca;
                else if (ca.kind == NodeKind::Surface) c = ca;
                else if (cb.kind == NodeKind::Surface) c = cb;
            }
            for (int j = 1; j <= k; ++j) {
                const double t = static_cast<double>(j) / (k + 1);
                mesh.nodes[base[e] + j - 1] = mesh.nodes[a] + t * (mesh.nodes[b] - mesh.nodes[a]);
                mesh.nodeClass[base[e] + j - 1] = c;
            }
        }
    });
    return base;
}

// Point t (0..k+1) along the sheet edge of hex h (corners `old`, crossed in
// direction d) that starts at corner c.
Index pointAlong(const Topology& topo, const std::vector<Index>& base, int k, Index h, const Hex& old, int d, int c,
                 int t) {
    int ref[3] = {kRef[c][0], kRef[c][1], kRef[c][2]};
    ref[d] = 1;
    const int other = cornerAt(ref[0], ref[1], ref[2]);
    if (t == 0) return old[c];
    if (t == k + 1) return old[other];
    int le = -1;
    for (int e = 4 * d; e < 4 * d + 4; ++e) {
        const auto& p = hexcell::kEdges[e];
        if ((p[0] == c && p[1] == other) || (p[1] == c && p[0] == other)) le = e;
    }
    const Index e = topo.hexEdges[h][le];
    return topo.edges[e][0] == old[c] ? base[e] + t - 1 : base[e] + (k + 1 - t) - 1;
}

// Splits each sheet hex into k+1 along its direction: the first keeps the
// hex's index, the others are appended in sheet-hex order.
void splitHexes(HexMesh& mesh, const Topology& topo, const std::vector<std::pair<Index, int>>& hexDir,
                const std::vector<Index>& base, int k) {
    const std::size_t H = mesh.hexCount();
    mesh.hexes.resize(H + hexDir.size() * k);
    mesh.material.resize(H + hexDir.size() * k);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, hexDir.size(), 256), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const auto [h, d] = hexDir[i];
            const Hex old = mesh.hexes[h];
            for (int j = 0; j <= k; ++j) {
                Hex sub;
                for (int c = 0; c < 8; ++c) {
                    int ref[3] = {kRef[c][0], kRef[c][1], kRef[c][2]};
                    const int up = ref[d];
                    ref[d] = 0;
                    sub[c] = pointAlong(topo, base, k, h, old, d, cornerAt(ref[0], ref[1], ref[2]), j + up);
                }
                const std::size_t slot = j == 0 ? static_cast<std::size_t>(h) : H + i * k + (j - 1);
                mesh.hexes[slot] = sub;
                mesh.material[slot] = mesh.material[h];
            }
        }
    });
}

}  // namespace

std::size_t dice(HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet, int copies) {
    if (copies < 1) throw Error("dice: the number of copies must be at least 1 (got " + std::to_string(copies) + ")");
    if (sheet < 0 || static_cast<std::size_t>(sheet) >= sheets.count())
        throw Error("dice: no sheet " + std::to_string(sheet));
    const std::vector<std::pair<Index, int>> hexDir = sheetHexDirections(sheets, sheet);
    const std::vector<Index> base = addEdgeNodes(mesh, topo, sheets, sheet, copies);
    splitHexes(mesh, topo, hexDir, base, copies);
    return hexDir.size() * copies;
}

}  // namespace isohex

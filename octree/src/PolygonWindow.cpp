// The polygoniser's surface in a window of the grid (see PolygonWindow.hpp).
#include "PolygonWindow.hpp"

#include <algorithm>
#include <cstdlib>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/TopologyMatch.hpp"

namespace isohex::octree {

namespace {

// The exact local test with the polygoniser's own cell table (see
// CellEdgeGroups). Toggling a point changes the signs of the cells around it
// only; the surface's vertices are (cell, vertex of the cell's pattern), its
// faces the crossed grid edges (each joining the vertices of the 4 cells
// around it that hold the edge). Take the cells R whose lowest corner is
// within -2..1 of the point on every axis and the grid edges within -2..2
// (every face touching a vertex in R): the faces, the vertices in R and the
// edges with an end in R are all that can change. The global surface keeps
// its Euler characteristic when V(R) - E(R) + F(box) does, and its components
// when the faces in the box join the vertices of the cells outside R (the
// ports) in the same groups and leave as many pieces without a port.
struct McWindow {
    static constexpr int kCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1},
                                          {0, 1, 0}, {1, 1, 0}, {1, 1, 1}, {0, 1, 1}};
    // per axis: the 4 cells around a grid edge in cyclic order (lowest corner
    // offset from the edge's start) and the cell edge (1..12) it is in each
    std::array<std::array<std::array<int, 3>, 4>, 3> cell{};
    std::array<std::array<int, 4>, 3> edge{};
    McWindow() {
        constexpr int kEdge[12][2] = {{0, 1}, {1, 2}, {3, 2}, {0, 3}, {4, 5}, {5, 6},
                                      {7, 6}, {4, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
        const int ring[4][2] = {{-1, -1}, {0, -1}, {0, 0}, {-1, 0}};
        for (int a = 0; a < 3; ++a)
            for (int n = 0; n < 4; ++n) {
                const int b = (a + 1) % 3, c = (a + 2) % 3;
                auto& o = cell[a][n];
                o[a] = 0;
                o[b] = ring[n][0];
                o[c] = ring[n][1];
                // the edge's ends in the cell's own coordinates
                int lo[3], hi[3];
                for (int d = 0; d < 3; ++d) lo[d] = hi[d] = -o[d];
                hi[a] = 1;
                for (int e = 0; e < 12; ++e) {
                    const int* u = kCorner[kEdge[e][0]];
                    const int* v = kCorner[kEdge[e][1]];
                    const bool same = (u[0] == lo[0] && u[1] == lo[1] && u[2] == lo[2] && v[0] == hi[0] &&
                                       v[1] == hi[1] && v[2] == hi[2]) ||
                                      (v[0] == lo[0] && v[1] == lo[1] && v[2] == lo[2] && u[0] == hi[0] &&
                                       u[1] == hi[1] && u[2] == hi[2]);
                    if (same) edge[a][n] = e + 1;
                }
            }
    }
};
const McWindow kMcWindow;

// Pattern of a cell as the polygoniser uses it: its signs, inverted when its
// ambiguous face meets the opposite ambiguous face of its neighbour.
inline std::uint8_t correctedSigns(std::uint8_t raw, std::uint8_t neighbourRaw, const CellEdgeGroups& t) {
    static constexpr std::uint8_t kOpposite[7] = {0, 3, 4, 1, 2, 6, 5};
    const std::uint8_t f = t.ambiguousFace[raw];
    return f != 0 && t.ambiguousFace[neighbourRaw] == kOpposite[f] ? static_cast<std::uint8_t>(~raw) : raw;
}

}  // namespace

void mcLocal(const std::vector<std::uint8_t>& in, const McBox& b, const CellEdgeGroups& t, McLocal& out) {
    const int w0 = b.w(0), w1 = b.w(1), w2 = b.w(2);
    auto pt = [&](int x, int y, int z) { return x + w0 * (y + w1 * z); };
    // raw patterns of the cells with lowest corner at window points 0..w-2
    const int r0 = w0 - 1, r1 = w1 - 1, r2 = w2 - 1;
    // scratch buffers kept per thread (the searches call this many times)
    static thread_local std::vector<std::uint8_t> raw, signs;
    static thread_local DisjointSets<std::int32_t> sets;
    static thread_local std::vector<std::uint64_t> edgeSeen;  // bit per possible polygon edge
    static thread_local std::vector<std::uint8_t> inRegion;
    static thread_local std::vector<std::int32_t> firstPort;
    raw.resize(static_cast<std::size_t>(r0) * r1 * r2);
    int corner[8];  // offsets of a cell's corners from its lowest one in `in`
    for (int v = 0; v < 8; ++v) corner[v] = pt(McWindow::kCorner[v][0], McWindow::kCorner[v][1], McWindow::kCorner[v][2]);
    for (int z = 0; z < r2; ++z)
        for (int y = 0; y < r1; ++y) {
            const std::uint8_t* row = in.data() + pt(0, y, z);
            std::uint8_t* patterns = raw.data() + r0 * (y + r1 * z);
            for (int x = 0; x < r0; ++x) {
                const std::uint8_t* c = row + x;
                patterns[x] = static_cast<std::uint8_t>((c[corner[0]] != 0) | (c[corner[1]] != 0) << 1 | (c[corner[2]] != 0) << 2 |
                                                   (c[corner[3]] != 0) << 3 | (c[corner[4]] != 0) << 4 |
                                                   (c[corner[5]] != 0) << 5 | (c[corner[6]] != 0) << 6 |
                                                   (c[corner[7]] != 0) << 7);
            }
        }
    // corrected patterns of the cells at window points 1..w-3 (index 0..w-4)
    const int s0 = w0 - 3, s1 = w1 - 3, s2 = w2 - 3;
    auto cid = [&](int x, int y, int z) { return x + s0 * (y + s1 * z); };
    const int cells = s0 * s1 * s2;
    signs.resize(cells);
    static constexpr int kFace[7][3] = {{0, 0, 0}, {0, 0, -1}, {1, 0, 0}, {0, 0, 1}, {-1, 0, 0}, {0, -1, 0}, {0, 1, 0}};
    for (int z = 0; z < s2; ++z)
        for (int y = 0; y < s1; ++y)
            for (int x = 0; x < s0; ++x) {
                const std::uint8_t r = raw[(x + 1) + r0 * ((y + 1) + r1 * (z + 1))];
                const int f = t.ambiguousFace[r];
                const std::uint8_t nb =
                    raw[(x + 1 + kFace[f][0]) + r0 * ((y + 1 + kFace[f][1]) + r1 * (z + 1 + kFace[f][2]))];
                signs[cid(x, y, z)] = correctedSigns(r, nb, t);
            }
    const auto& g = t.edgeGroups;
    inRegion.resize(cells);
    for (int z = 0; z < s2; ++z)
        for (int y = 0; y < s1; ++y)
            for (int x = 0; x < s0; ++x)
                inRegion[cid(x, y, z)] = x >= 1 && x <= s0 - 2 && y >= 1 && y <= s1 - 2 && z >= 1 && z <= s2 - 2;
    auto inR = [&](int c) { return inRegion[c] != 0; };
    sets.reset(static_cast<std::size_t>(cells) * 4);
    auto find = [&](int a) -> int { return sets.find(a); };
    long long v = 0, f = 0;
    for (int c = 0; c < cells; ++c)
        if (inR(c)) v += g[signs[c]][0];
    // A polygon edge joins vertices of two cells sharing a face: counted
    // once by (lower cell, its vertex, axis, the other cell's vertex).
    edgeSeen.assign((static_cast<std::size_t>(cells) * 48 + 63) / 64, 0);
    long long polyEdges = 0;
    const int step[3] = {1, s0, s0 * s1};
    // grid edges with both ends at window points 2..w-3 (offsets -2..k+1;
    // cell index = window point index - 1)
    const int hi[3] = {w0 - 3, w1 - 3, w2 - 3};
    for (int a = 0; a < 3; ++a)
        for (int z = 2; z <= hi[2]; ++z)
            for (int y = 2; y <= hi[1]; ++y)
                for (int x = 2; x <= hi[0]; ++x) {
                    int e[3] = {x, y, z};
                    ++e[a];
                    if (e[a] > hi[a]) continue;
                    if (in[pt(x, y, z)] == in[pt(e[0], e[1], e[2])]) continue;
                    ++f;
                    int vert[4], cellOf[4];
                    for (int n = 0; n < 4; ++n) {
                        const auto& o = kMcWindow.cell[a][n];
                        const int c = cid(x - 1 + o[0], y - 1 + o[1], z - 1 + o[2]);
                        const int gr = g[signs[c]][kMcWindow.edge[a][n]];
                        cellOf[n] = c;
                        vert[n] = c * 4 + std::max(gr - 1, 0);
                    }
                    for (int n = 0; n < 4; ++n) {
                        const int p = vert[n], q = vert[(n + 1) % 4];
                        sets.unite(p, q);
                        const int c1 = cellOf[n], c2 = cellOf[(n + 1) % 4];
                        if (!inR(c1) && !inR(c2)) continue;
                        const int d = std::abs(c1 - c2);
                        const int axis = d == step[0] ? 0 : d == step[1] ? 1 : 2;
                        const int lowVert = c1 < c2 ? p : q, highVert = c1 < c2 ? q : p;
                        const std::size_t key =
                            ((static_cast<std::size_t>(lowVert) * 3 + axis) * 4) + static_cast<std::size_t>(highVert % 4);
                        std::uint64_t& word = edgeSeen[key >> 6];
                        const std::uint64_t bit = std::uint64_t{1} << (key & 63);
                        if (!(word & bit)) {
                            word |= bit;
                            ++polyEdges;
                        }
                    }
                }
    out.chi = v - polyEdges + f;
    // ports: the vertices of the cells outside R, in a fixed order
    firstPort.assign(static_cast<std::size_t>(cells) * 4, -1);
    out.portGroup.assign(static_cast<std::size_t>(cells) * 4, -1);
    for (int c = 0; c < cells; ++c) {
        if (inR(c)) continue;
        for (int k = 0; k < g[signs[c]][0]; ++k) {
            const int p = c * 4 + k, r = find(p);
            if (firstPort[r] < 0) firstPort[r] = p;
            out.portGroup[p] = firstPort[r];
        }
    }
    out.closed = 0;
    for (int c = 0; c < cells; ++c) {
        if (!inR(c)) continue;
        for (int k = 0; k < g[signs[c]][0]; ++k) {
            const int p = c * 4 + k;
            if (find(p) == p && firstPort[p] < 0) ++out.closed;
        }
    }
}

void fillWindow(const Labels& l, const std::array<int, 3>& lo, const McBox& b, std::int32_t m,
                std::vector<std::uint8_t>& in) {
    const auto [nx, ny, nz] = l.grid.dims;
    const int w0 = b.w(0), w1 = b.w(1), w2 = b.w(2);
    in.resize(b.points());
    for (int z = 0; z < w2; ++z)
        for (int y = 0; y < w1; ++y)
            for (int x = 0; x < w0; ++x) {
                const int i = lo[0] + x - 4, j = lo[1] + y - 4, k = lo[2] + z - 4;
                const bool inside = i >= 0 && j >= 0 && k >= 0 && i < nx && j < ny && k < nz;
                in[x + w0 * (y + w1 * z)] = inside && l.material[l.grid.index(i, j, k)] == m;
            }
}

bool mcKeeps(const Labels& l, const std::vector<PointChange>& changes, std::int32_t m, const CellEdgeGroups& t,
             long long* eulerChange) {
    const auto [nx, ny, nz] = l.grid.dims;
    std::array<int, 3> lo{nx, ny, nz}, hi{-1, -1, -1};
    for (const auto& [p, to] : changes) {
        const auto c = l.grid.coords(p);
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], c[a]);
            hi[a] = std::max(hi[a], c[a]);
        }
    }
    McBox box;
    for (int a = 0; a < 3; ++a) box.k[a] = hi[a] - lo[a] + 1;
    const int w0 = box.w(0), w1 = box.w(1);
    std::vector<std::uint8_t> in;
    fillWindow(l, lo, box, m, in);
    McLocal before, after;
    mcLocal(in, box, t, before);
    for (const auto& [p, to] : changes) {
        const auto c = l.grid.coords(p);
        in[(c[0] - lo[0] + 4) + w0 * ((c[1] - lo[1] + 4) + w1 * (c[2] - lo[2] + 4))] = to == m;
    }
    mcLocal(in, box, t, after);
    if (eulerChange) *eulerChange = after.chi - before.chi;
    return before.chi == after.chi && before.closed == after.closed && before.portGroup == after.portGroup;
}

bool mcKeeps(const Labels& l, int i, int j, int k, std::int32_t m, const CellEdgeGroups& t,
             long long* eulerChange) {
    const std::size_t p = l.grid.index(i, j, k);
    const std::int32_t to = l.material[p] == m ? m + 1 : m;  // toggles m there (any other material is outside m)
    return mcKeeps(l, {PointChange{p, to}}, m, t, eulerChange);
}

}  // namespace isohex::octree

// Grid labelling, non-manifold repair and region topology.
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <sstream>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/octree/DualContour.hpp"

namespace isohex::octree {

std::array<double, 3> Grid::spacing() const {
    std::array<double, 3> s;
    for (int a = 0; a < 3; ++a)
        s[a] = std::sqrt(axes[a][0] * axes[a][0] + axes[a][1] * axes[a][1] + axes[a][2] * axes[a][2]);
    return s;
}

double Grid::determinant() const {
    const auto& a = axes[0];
    const auto& b = axes[1];
    const auto& c = axes[2];
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

Labels sampleLabels(const Domain& domain, const Grid& grid, bool keepBorder) {
    Labels l;
    l.grid = grid;
    l.material.assign(grid.size(), 0);
    const auto [nx, ny, nz] = grid.dims;
    tbb::parallel_for(tbb::blocked_range<int>(0, nz), [&](const auto& r) {
        for (int k = r.begin(); k != r.end(); ++k)
            for (int j = 0; j < ny; ++j)
                for (int i = 0; i < nx; ++i) {
                    const bool border = i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1;
                    if (border && !keepBorder) continue;
                    l.material[grid.index(i, j, k)] = domain.materialAt(grid.point(i, j, k));
                }
    });
    return l;
}

namespace {

// Corner b of a 2x2x2 block is offset (b & 1, b >> 1 & 1, b >> 2 & 1).
// kManifold[p]: the corners in bit set p, and those not in it, are each empty
// or 6-connected inside the block (corners adjacent when they differ in one bit).
struct ManifoldTable {
    std::array<bool, 256> ok{};
    // how far from manifold: 1 for the set and 1 for its complement when not
    // 6-connected inside the block (a repair step that mends one side counts)
    std::array<int, 256> pieces{};
    ManifoldTable() {
        auto connected = [](unsigned set) {
            if (set == 0) return true;
            unsigned seen = set & (~set + 1), frontier = seen;
            while (frontier) {
                unsigned next = 0;
                for (int b = 0; b < 8; ++b)
                    if (frontier >> b & 1)
                        for (int d = 0; d < 3; ++d) {
                            const unsigned nb = 1u << (b ^ (1 << d));
                            if ((set & nb) && !(seen & nb)) next |= nb;
                        }
                seen |= next;
                frontier = next;
            }
            return seen == set;
        };
        for (unsigned p = 0; p < 256; ++p) {
            ok[p] = connected(p) && connected(~p & 0xFFu);
            pieces[p] = !connected(p) + !connected(~p & 0xFFu);
        }
    }
};
const ManifoldTable kTable;

struct BlockView {
    std::array<std::size_t, 8> point;
    std::array<std::int32_t, 8> mat;
};

BlockView block(const Labels& l, int i, int j, int k) {
    BlockView b;
    for (int c = 0; c < 8; ++c) {
        b.point[c] = l.grid.index(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1));
        b.mat[c] = l.material[b.point[c]];
    }
    return b;
}

// With three or more materials in a block, each interface between two of them
// must also be one fan around the block centre: the block edges joining an
// a-point to a b-point are the interface's faces there, and two of them are
// joined across a block square holding exactly two such edges.
int badPairs(const std::array<std::int32_t, 8>& mat) {
    std::array<std::int32_t, 8> distinct{};
    int nd = 0;
    for (int c = 0; c < 8; ++c) {
        bool seen = false;
        for (int e = 0; e < nd; ++e) seen = seen || distinct[e] == mat[c];
        if (!seen) distinct[nd++] = mat[c];
    }
    if (nd < 3) return 0;
    // block edges: corner c to c | (1 << d) where bit d of c is clear
    static constexpr auto edges = [] {
        std::array<std::array<int, 2>, 12> e{};
        int n = 0;
        for (int c = 0; c < 8; ++c)
            for (int d = 0; d < 3; ++d)
                if (!(c >> d & 1)) e[n++] = {c, c | (1 << d)};
        return e;
    }();
    // block squares: the 6 faces, each listing its 4 edges by index
    static constexpr auto squares = [] {
        std::array<std::array<int, 4>, 6> sq{};
        int n = 0;
        for (int d = 0; d < 3; ++d)
            for (int side = 0; side < 2; ++side) {
                int k = 0;
                for (int e = 0; e < 12; ++e)
                    if (((edges[e][0] >> d & 1) == side) && ((edges[e][1] >> d & 1) == side)) sq[n][k++] = e;
                ++n;
            }
        return sq;
    }();
    int bad = 0;
    for (int x = 0; x < nd; ++x)
        for (int y = x + 1; y < nd; ++y) {
            const std::int32_t a = distinct[x], b = distinct[y];
            unsigned faces = 0;
            for (int e = 0; e < 12; ++e) {
                const std::int32_t p = mat[edges[e][0]], q = mat[edges[e][1]];
                if ((p == a && q == b) || (p == b && q == a)) faces |= 1u << e;
            }
            if (faces == 0) continue;
            FixedDisjointSets<int, 12> sets;
            for (const auto& sq : squares) {
                int in[4], n = 0;
                for (int e : sq)
                    if (faces >> e & 1) in[n++] = e;
                if (n == 2) sets.unite(in[0], in[1]);
            }
            int components = 0;
            for (int e = 0; e < 12; ++e)
                if ((faces >> e & 1) && sets.isRoot(e)) ++components;
            bad += components > 1;
        }
    return bad;
}

// Sums score(pattern) over the materials of a block, where pattern has bit d
// set for the corners d holding that material.
template <class Score>
int sumOverMaterials(const std::array<std::int32_t, 8>& mat, Score score) {
    int sum = 0;
    for (int c = 0; c < 8; ++c) {
        bool first = true;
        for (int d = 0; d < c; ++d)
            if (mat[d] == mat[c]) first = false;
        if (!first) continue;
        unsigned p = 0;
        for (int d = 0; d < 8; ++d)
            if (mat[d] == mat[c]) p |= 1u << d;
        sum += score(p);
    }
    return sum;
}

int badMaterials(const std::array<std::int32_t, 8>& mat) {
    return sumOverMaterials(mat, [](unsigned p) { return kTable.ok[p] ? 0 : 1; }) + badPairs(mat);
}

bool blockManifold(const std::array<std::int32_t, 8>& mat) { return badMaterials(mat) == 0; }

// As badMaterials, but a material whose points and whose complement are both
// split inside the block counts twice: zero exactly when badMaterials is.
int badness(const std::array<std::int32_t, 8>& mat) {
    return sumOverMaterials(mat, [](unsigned p) { return static_cast<int>(kTable.pieces[p]); }) + badPairs(mat);
}

bool uniformBlock(const std::array<std::int32_t, 8>& mat) {
    for (int c = 1; c < 8; ++c)
        if (mat[c] != mat[0]) return false;
    return true;
}

// Lowest-corner indices of the non-manifold blocks, sorted.
std::vector<std::size_t> badBlocks(const Labels& l) {
    const auto [nx, ny, nz] = l.grid.dims;
    tbb::enumerable_thread_specific<std::vector<std::size_t>> local;
    if (nx < 2 || ny < 2 || nz < 2) return {};
    tbb::parallel_for(tbb::blocked_range<int>(0, nz - 1), [&](const auto& r) {
        auto& out = local.local();
        for (int k = r.begin(); k != r.end(); ++k)
            for (int j = 0; j < ny - 1; ++j) {
                // rows of the two z-layers of the blocks, x fastest
                const std::int32_t* row[4] = {&l.material[l.grid.index(0, j, k)], &l.material[l.grid.index(0, j + 1, k)],
                                              &l.material[l.grid.index(0, j, k + 1)],
                                              &l.material[l.grid.index(0, j + 1, k + 1)]};
                for (int i = 0; i < nx - 1; ++i) {
                    const std::int32_t m0 = row[0][i];
                    if (row[0][i + 1] == m0 && row[1][i] == m0 && row[1][i + 1] == m0 && row[2][i] == m0 &&
                        row[2][i + 1] == m0 && row[3][i] == m0 && row[3][i + 1] == m0)
                        continue;  // uniform: manifold
                    const BlockView b = block(l, i, j, k);
                    if (!blockManifold(b.mat)) out.push_back(l.grid.index(i, j, k));
                }
            }
    });
    std::vector<std::size_t> all;
    for (auto& v : local) all.insert(all.end(), v.begin(), v.end());
    std::sort(all.begin(), all.end());
    return all;
}

// The non-manifold blocks among `candidates` (lowest-corner indices), sorted.
std::vector<std::size_t> badBlocksAmong(const Labels& l, std::vector<std::size_t> candidates) {
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    const auto [nx, ny, nz] = l.grid.dims;
    std::vector<std::size_t> out;
    for (std::size_t b : candidates) {
        const int i = static_cast<int>(b % nx), j = static_cast<int>(b / nx % ny), k = static_cast<int>(b / nx / ny);
        if (i >= nx - 1 || j >= ny - 1 || k >= nz - 1) continue;
        const BlockView v = block(l, i, j, k);
        if (!uniformBlock(v.mat) && !blockManifold(v.mat)) out.push_back(b);
    }
    return out;
}

// Change of the Euler characteristic of material m's solid (the union of the
// closed cubes around its points) when point (i, j, k) joins it (`add`) or
// leaves it: the point's cube meets the cubes of its m-neighbours in a complex
// K of its faces, edges and vertices, and chi changes by +-(1 - chi(K)). The
// boundary surface's chi is twice the solid's, so 0 means the flip keeps the
// Euler characteristic that regionTopology reports.
int eulerChange(const Labels& l, int i, int j, int k, std::int32_t m, bool add) {
    const auto [nx, ny, nz] = l.grid.dims;
    bool in[3][3][3];
    for (int a = -1; a <= 1; ++a)
        for (int b = -1; b <= 1; ++b)
            for (int c = -1; c <= 1; ++c) {
                const int x = i + a, y = j + b, z = k + c;
                const bool inside = x >= 0 && y >= 0 && z >= 0 && x < nx && y < ny && z < nz;
                in[a + 1][b + 1][c + 1] = (a || b || c) && inside && l.material[l.grid.index(x, y, z)] == m;
            }
    int chi = 0;
    // The cells of the point's cube are indexed by offsets s != 0 in {-1,0,1}^3:
    // a face (one non-zero axis), an edge (two) or a vertex (three). A cell is
    // in K when an m-neighbour at offset t shares it: t != 0 with t_a in
    // {0, s_a} on every axis.
    for (int a = -1; a <= 1; ++a)
        for (int b = -1; b <= 1; ++b)
            for (int c = -1; c <= 1; ++c) {
                const int nonzero = (a != 0) + (b != 0) + (c != 0);
                if (nonzero == 0) continue;
                bool inK = false;
                for (int ta = std::min(a, 0); ta <= std::max(a, 0) && !inK; ++ta)
                    for (int tb = std::min(b, 0); tb <= std::max(b, 0) && !inK; ++tb)
                        for (int tc = std::min(c, 0); tc <= std::max(c, 0) && !inK; ++tc)
                            inK = in[ta + 1][tb + 1][tc + 1];
                if (inK) chi += nonzero == 1 ? 1 : nonzero == 2 ? -1 : 1;
            }
    return add ? 1 - chi : chi - 1;
}

// Topological number of the set `in` (3x3x3 neighbourhood, x fastest, the
// centre ignored) for 6- or 26-adjacency (Bertrand and Malandain 1994): with
// 6, the 6-components of the set within the 18-neighbourhood that hold a
// 6-neighbour of the centre; with 26, the 26-components in the 26-neighbourhood.
int topoNumber(const std::array<bool, 27>& in, int adjacency) {
    auto axes = [](int q) { return (q % 3 != 1) + (q / 3 % 3 != 1) + (q / 9 != 1); };
    std::array<bool, 27> use{};
    for (int q = 0; q < 27; ++q) use[q] = q != 13 && in[q] && (adjacency == 26 || axes(q) <= 2);
    std::array<bool, 27> seen{};
    int count = 0;
    for (int s = 0; s < 27; ++s) {
        if (!use[s] || seen[s]) continue;
        int stack[27], top = 0;
        stack[top++] = s;
        seen[s] = true;
        bool counts = adjacency == 26;
        while (top) {
            const int p = stack[--top];
            counts = counts || axes(p) == 1;
            for (int q = 0; q < 27; ++q) {
                if (!use[q] || seen[q]) continue;
                const int da = std::abs(p % 3 - q % 3), db = std::abs(p / 3 % 3 - q / 3 % 3), dc = std::abs(p / 9 - q / 9);
                if (da > 1 || db > 1 || dc > 1) continue;
                if (adjacency == 6 && da + db + dc != 1) continue;
                seen[q] = true;
                stack[top++] = q;
            }
        }
        count += counts;
    }
    return count;
}

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

// What mcLocal computes for one state of the window.
struct McLocal {
    long long chi = 0;
    int closed = 0;                           // pieces without a port
    std::array<std::int16_t, 864> portGroup;  // per vertex: first port of its piece (-1: not a port)
};

// Pattern of a cell as the polygoniser uses it: its signs, inverted when its
// ambiguous face meets the opposite ambiguous face of its neighbour.
inline std::uint8_t correctedSigns(std::uint8_t raw, std::uint8_t neighbourRaw, const CellEdgeGroups& t) {
    static constexpr std::uint8_t kOpposite[7] = {0, 3, 4, 1, 2, 6, 5};
    const std::uint8_t f = t.ambiguousFace[raw];
    return f != 0 && t.ambiguousFace[neighbourRaw] == kOpposite[f] ? static_cast<std::uint8_t>(~raw) : raw;
}

// in: the window's points (offsets -4..4, x fastest), true when inside.
void mcLocal(const std::array<bool, 729>& in, const CellEdgeGroups& t, McLocal& out) {
    auto pt = [](int x, int y, int z) { return x + 9 * (y + 9 * z); };
    // raw patterns of the cells with lowest corner at offsets -4..3 (index 0..7)
    std::array<std::uint8_t, 512> raw;
    for (int z = 0; z < 8; ++z)
        for (int y = 0; y < 8; ++y)
            for (int x = 0; x < 8; ++x) {
                unsigned sg = 0;
                for (int v = 0; v < 8; ++v)
                    if (in[pt(x + McWindow::kCorner[v][0], y + McWindow::kCorner[v][1], z + McWindow::kCorner[v][2])])
                        sg |= 1u << v;
                raw[x + 8 * (y + 8 * z)] = static_cast<std::uint8_t>(sg);
            }
    // patterns of the cells at offsets -3..2 (index 0..5 here, 1..6 in raw)
    auto cid = [](int x, int y, int z) { return x + 6 * (y + 6 * z); };
    std::array<std::uint8_t, 216> signs;
    static constexpr int kFace[7][3] = {{0, 0, 0}, {0, 0, -1}, {1, 0, 0}, {0, 0, 1}, {-1, 0, 0}, {0, -1, 0}, {0, 1, 0}};
    for (int z = 0; z < 6; ++z)
        for (int y = 0; y < 6; ++y)
            for (int x = 0; x < 6; ++x) {
                const std::uint8_t r = raw[(x + 1) + 8 * ((y + 1) + 8 * (z + 1))];
                const int f = t.ambiguousFace[r];
                const std::uint8_t nb =
                    raw[(x + 1 + kFace[f][0]) + 8 * ((y + 1 + kFace[f][1]) + 8 * (z + 1 + kFace[f][2]))];
                signs[cid(x, y, z)] = correctedSigns(r, nb, t);
            }
    const auto& g = t.edgeGroups;
    auto inR = [](int c) {
        const int x = c % 6, y = c / 6 % 6, z = c / 36;
        return x >= 1 && x <= 4 && y >= 1 && y <= 4 && z >= 1 && z <= 4;
    };
    FixedDisjointSets<std::int16_t, 864> sets;
    auto find = [&](int a) -> int { return sets.find(static_cast<std::int16_t>(a)); };
    long long v = 0, f = 0;
    for (int c = 0; c < 216; ++c)
        if (inR(c)) v += g[signs[c]][0];
    std::array<std::uint32_t, 1200> edges;
    int ne = 0;
    // grid edges within the box: points at offsets -2..2 (window 2..6; cell
    // index = window point index - 1)
    for (int a = 0; a < 3; ++a)
        for (int z = 2; z <= 6; ++z)
            for (int y = 2; y <= 6; ++y)
                for (int x = 2; x <= 6; ++x) {
                    int e[3] = {x, y, z};
                    ++e[a];
                    if (e[a] > 6) continue;
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
                        sets.unite(static_cast<std::int16_t>(p), static_cast<std::int16_t>(q));
                        if (inR(cellOf[n]) || inR(cellOf[(n + 1) % 4]))
                            edges[ne++] = static_cast<std::uint32_t>(std::min(p, q)) << 16 |
                                          static_cast<std::uint32_t>(std::max(p, q));
                    }
                }
    std::sort(edges.begin(), edges.begin() + ne);
    const long long e = std::unique(edges.begin(), edges.begin() + ne) - edges.begin();
    out.chi = v - e + f;
    // ports: the vertices of the cells outside R, in a fixed order
    std::array<std::int16_t, 864> firstPort;
    firstPort.fill(-1);
    out.portGroup.fill(-1);
    for (int c = 0; c < 216; ++c) {
        if (inR(c)) continue;
        for (int k = 0; k < g[signs[c]][0]; ++k) {
            const int p = c * 4 + k, r = find(p);
            if (firstPort[r] < 0) firstPort[r] = static_cast<std::int16_t>(p);
            out.portGroup[p] = firstPort[r];
        }
    }
    out.closed = 0;
    for (int c = 0; c < 216; ++c) {
        if (!inR(c)) continue;
        for (int k = 0; k < g[signs[c]][0]; ++k) {
            const int p = c * 4 + k;
            if (find(p) == p && firstPort[p] < 0) ++out.closed;
        }
    }
}

// Whether point (i, j, k) joining or leaving material m keeps the components
// and Euler characteristic of the polygoniser's surface of m (m's points
// inside, every other point outside).
// (eulerChange: the change of the surface's Euler characteristic, exact.)
bool mcKeeps(const Labels& l, int i, int j, int k, std::int32_t m, const CellEdgeGroups& t,
             long long* eulerChange = nullptr) {
    const auto [nx, ny, nz] = l.grid.dims;
    std::array<bool, 729> in{};
    for (int z = 0; z < 9; ++z)
        for (int y = 0; y < 9; ++y)
            for (int x = 0; x < 9; ++x) {
                const int a = i + x - 4, b = j + y - 4, c = k + z - 4;
                const bool inside = a >= 0 && b >= 0 && c >= 0 && a < nx && b < ny && c < nz;
                in[x + 9 * (y + 9 * z)] = inside && l.material[l.grid.index(a, b, c)] == m;
            }
    McLocal before, after;
    mcLocal(in, t, before);
    const int centre = 4 + 9 * (4 + 9 * 4);
    in[centre] = !in[centre];
    mcLocal(in, t, after);
    if (eulerChange) *eulerChange = after.chi - before.chi;
    return before.chi == after.chi && before.closed == after.closed && before.portGroup == after.portGroup;
}

// Region ids of the repair (see repairNonManifold): union-find over ids, so a
// flip that has to join two regions merges their ids.
struct RegionIds {
    std::vector<std::int32_t> id;        // per grid point (meaningful for material points)
    DisjointSets<std::int32_t> regions;  // over the ids (root: the smallest id of the merged ones)
    std::int32_t of(std::size_t p) { return regions.find(id[p]); }
    std::int32_t fresh() { return regions.add(); }
};

// Whether point (i, j, k) may leave material `from` and join `to` without
// changing the topology of the surface volumeToMesh draws around either: a
// material's region (its points with one region id, 26-adjacent, as marching
// cubes joins points touching along an edge or at a corner unless they belong
// to regions it keeps apart) against everything else (6-adjacent, as marching
// cubes never joins pockets of the outside through an edge) keeps its
// components, tunnels and cavities: the point is simple for both (topological
// numbers 1 and 1). A point joining `to` must touch exactly one of its regions.
// 2 when the flip is simple for both materials; 1 when only what lies
// outside them keeps its topology (the model of the regions is coarser than
// marching cubes, that of the outside matches it); 0 otherwise.
int flipTier(const Labels& l, RegionIds& r, int i, int j, int k, std::int32_t from, std::int32_t to,
             const CellEdgeGroups* mc) {
    const auto [nx, ny, nz] = l.grid.dims;
    std::array<std::int32_t, 27> mat;
    std::array<std::size_t, 27> pt{};
    for (int q = 0; q < 27; ++q) {
        const int x = i + q % 3 - 1, y = j + q / 3 % 3 - 1, z = k + q / 9 - 1;
        const bool inside = x >= 0 && y >= 0 && z >= 0 && x < nx && y < ny && z < nz;
        pt[q] = inside ? l.grid.index(x, y, z) : 0;
        mat[q] = inside ? l.material[pt[q]] : 0;
    }
    bool regionKeeps = true, restKeeps = true;
    auto check = [&](std::int32_t m, std::int32_t region) {
        std::array<bool, 27> in{}, out{};
        for (int q = 0; q < 27; ++q) {
            if (q == 13) continue;
            in[q] = region >= 0 && mat[q] == m && r.of(pt[q]) == region;
            out[q] = mat[q] != m;
        }
        regionKeeps = regionKeeps && region >= 0 && topoNumber(in, 26) == 1;
        restKeeps = restKeeps && topoNumber(out, 6) == 1;
    };
    if (from != 0) check(from, r.of(pt[13]));
    if (to != 0) {
        std::int32_t region = -1;
        bool several = false;
        for (int q = 0; q < 27; ++q) {
            if (q == 13 || mat[q] != to) continue;
            const std::int32_t o = r.of(pt[q]);
            several = several || (region >= 0 && o != region);
            region = o;
        }
        check(to, several ? -1 : region);
    }
    const int model = restKeeps ? (regionKeeps ? 2 : 1) : 0;
    if (!mc) return model;
    // with the polygoniser's tables: 3 when the flip keeps both surfaces
    // exactly; 2 when it keeps the Euler characteristic of both (it may join
    // or split pieces: one tunnel for one component); else the model's tier
    long long dFrom = 0, dTo = 0;
    const bool exact = (from == 0 || mcKeeps(l, i, j, k, from, *mc, &dFrom)) &&
                       (to == 0 || mcKeeps(l, i, j, k, to, *mc, &dTo));
    if (exact) return 3;
    // (a flip that fails for `from` does not test `to`: test it for the Euler change)
    if (from != 0 && to != 0 && dTo == 0) mcKeeps(l, i, j, k, to, *mc, &dTo);
    return dFrom == 0 && dTo == 0 ? 2 : std::min(model, 1);
}

bool simpleFlip(const Labels& l, RegionIds& r, int i, int j, int k, std::int32_t from, std::int32_t to,
                const CellEdgeGroups* mc) {
    return flipTier(l, r, i, j, k, from, to, mc) == (mc ? 3 : 2);
}

// Gives point p material `to`, with the region id of its new neighbours
// (merging their regions if it touches several; a fresh region if none).
void flipPoint(Labels& l, RegionIds& r, std::size_t p, std::int32_t to) {
    l.material[p] = to;
    if (to == 0) return;
    const auto [nx, ny, nz] = l.grid.dims;
    const int i = static_cast<int>(p % nx), j = static_cast<int>(p / nx % ny), k = static_cast<int>(p / nx / ny);
    std::int32_t region = -1;
    for (int q = 0; q < 27; ++q) {
        const int x = i + q % 3 - 1, y = j + q / 3 % 3 - 1, z = k + q / 9 - 1;
        if (q == 13 || x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
        const std::size_t o = l.grid.index(x, y, z);
        if (l.material[o] != to) continue;
        const std::int32_t ro = r.of(o);
        if (region < 0) region = ro;
        else if (ro != region)
            region = r.regions.unite(ro, region);
    }
    r.id[p] = region >= 0 ? region : r.fresh();
}

}  // namespace

bool flipKeepsPolygonTopology(const Labels& labels, int i, int j, int k, std::int32_t to, const CellEdgeGroups& table,
                              long long* eulerChange) {
    const std::int32_t from = labels.material[labels.grid.index(i, j, k)];
    if (from == to) {
        if (eulerChange) *eulerChange = 0;
        return true;
    }
    long long dFrom = 0, dTo = 0;
    const bool keepsFrom = from == 0 || mcKeeps(labels, i, j, k, from, table, &dFrom);
    const bool keepsTo = to == 0 || mcKeeps(labels, i, j, k, to, table, &dTo);
    if (eulerChange) *eulerChange = dFrom + dTo;
    return keepsFrom && keepsTo;
}

std::size_t countNonManifoldBlocks(const Labels& labels) { return badBlocks(labels).size(); }

std::size_t keepLargestComponents(Labels& labels) {
    const auto [nx, ny, nz] = labels.grid.dims;
    const std::size_t n = labels.material.size();
    DisjointSets<std::uint32_t> sets(n);
    auto find = [&](std::size_t a) { return sets.find(static_cast<std::uint32_t>(a)); };
    auto unite = [&](std::size_t a, std::size_t b) {
        sets.unite(static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b));
    };
    const Grid& g = labels.grid;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t p = g.index(i, j, k);
                const std::int32_t m = labels.material[p];
                if (m == 0) continue;
                if (i + 1 < nx && labels.material[g.index(i + 1, j, k)] == m) unite(p, g.index(i + 1, j, k));
                if (j + 1 < ny && labels.material[g.index(i, j + 1, k)] == m) unite(p, g.index(i, j + 1, k));
                if (k + 1 < nz && labels.material[g.index(i, j, k + 1)] == m) unite(p, g.index(i, j, k + 1));
            }
    // size of each component, then the largest root per material (ties: smallest root)
    std::vector<std::uint32_t> size(n, 0);
    for (std::size_t p = 0; p < n; ++p)
        if (labels.material[p] != 0) ++size[find(p)];
    std::map<std::int32_t, std::uint32_t> best;
    for (std::size_t p = 0; p < n; ++p) {
        const std::int32_t m = labels.material[p];
        if (m == 0 || !sets.isRoot(static_cast<std::uint32_t>(p))) continue;
        auto it = best.find(m);
        if (it == best.end() || size[p] > size[it->second]) best[m] = static_cast<std::uint32_t>(p);
    }
    std::size_t removed = 0;
    for (std::size_t p = 0; p < n; ++p) {
        const std::int32_t m = labels.material[p];
        if (m != 0 && find(p) != best[m]) {
            labels.material[p] = 0;
            ++removed;
        }
    }
    return removed;
}

namespace {

// Region ids for the repair: the given ones, or each material's 26-connected
// components (points touching along an edge or at a corner in one region).
RegionIds initialRegions(const Labels& labels, const std::vector<std::int32_t>* given) {
    RegionIds r;
    const std::size_t n = labels.material.size();
    r.id.assign(n, 0);
    if (given) {
        if (given->size() != n) throw Error("repairNonManifold: one region id per grid point expected");
        std::map<std::int32_t, std::int32_t> dense;
        for (std::size_t p = 0; p < n; ++p)
            if (labels.material[p] != 0) {
                auto [it, fresh] = dense.emplace((*given)[p], static_cast<std::int32_t>(dense.size()));
                r.id[p] = it->second;
            }
        r.regions.reset(dense.size());
        return r;
    }
    const Grid& g = labels.grid;
    const auto [nx, ny, nz] = g.dims;
    DisjointSets<std::int32_t> sets(n);
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t p = g.index(i, j, k);
                const std::int32_t m = labels.material[p];
                if (m == 0) continue;
                // the 13 neighbours after p in x-fastest order
                for (int q = 14; q < 27; ++q) {
                    const int x = i + q % 3 - 1, y = j + q / 3 % 3 - 1, z = k + q / 9 - 1;
                    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
                    const std::size_t o = g.index(x, y, z);
                    if (labels.material[o] != m) continue;
                    sets.unite(static_cast<std::int32_t>(p), static_cast<std::int32_t>(o));
                }
            }
    std::map<std::int32_t, std::int32_t> dense;
    for (std::size_t p = 0; p < n; ++p)
        if (labels.material[p] != 0) {
            auto [it, fresh] = dense.emplace(sets.find(static_cast<std::int32_t>(p)), static_cast<std::int32_t>(dense.size()));
            r.id[p] = it->second;
        }
    r.regions.reset(dense.size());
    return r;
}

}  // namespace

RepairReport repairNonManifold(Labels& labels, const Domain& domain, const std::vector<std::int32_t>* regions,
                               const CellEdgeGroups* marchingCubes) {
    RepairReport rep;
    const Grid& g = labels.grid;
    const auto [nx, ny, nz] = g.dims;
    RegionIds ids = initialRegions(labels, regions);
    std::vector<std::uint8_t> flips(labels.material.size(), 0);
    bool plain = false;  // no topology preference (see the end of a round)
    constexpr int kMaxRounds = 200;
    // Pockets and specks can step back and forth between two contacts for a
    // few rounds before they settle (ch2bet); 6 flips per point instead of 4
    // gives them more rounds before a point is frozen (ch2bet 1 mm: chi 848
    // against 844, volumeToMesh of the scan 878; 8 to 16 give the same).
    constexpr int kMaxFlipsPerPoint = 6;
    auto isBorder = [&](int pi, int pj, int pk) {
        return pi == 0 || pj == 0 || pk == 0 || pi == nx - 1 || pj == ny - 1 || pk == nz - 1;
    };
    auto record = [&](std::size_t p, std::int32_t to) {
        if (labels.material[p] == 0) ++rep.pointsAdded;
        else if (to == 0) ++rep.pointsRemoved;
        else ++rep.pointsAdded;
        flipPoint(labels, ids, p, to);
        ++flips[p];
    };
    // A block can only turn bad when one of its points changes, so after the
    // first full scan each round looks at the blocks still bad and the blocks
    // around the points the previous round changed (the same set a full scan finds).
    std::vector<std::size_t> bad = badBlocks(labels);
    for (int round = 0;; ++round) {
        if (round > 0) bad = badBlocksAmong(labels, std::move(bad));
        if (round == 0) rep.nonManifoldBefore = bad.size();
        if (bad.empty()) {
            rep.rounds = round;
            return rep;
        }
        if (round == kMaxRounds)
            throw Error("non-manifold repair found no fixpoint after " + std::to_string(kMaxRounds) + " rounds (" +
                        std::to_string(bad.size()) + " bad places left); try a different --size or --iso");
        std::set<std::size_t> touched;  // points changed this round; their blocks wait for the next round
        for (std::size_t b : bad) {
            const int i = static_cast<int>(b % nx), j = static_cast<int>(b / nx % ny), k = static_cast<int>(b / nx / ny);
            BlockView v = block(labels, i, j, k);
            bool stale = false;
            for (std::size_t p : v.point) stale = stale || touched.count(p);
            if (stale) continue;
            const int badNow = badness(v.mat), badMaterialsNow = badMaterials(v.mat);
            // Candidates: give one corner to another material present in the block (or background).
            std::vector<std::int32_t> present(v.mat.begin(), v.mat.end());
            present.push_back(0);
            std::sort(present.begin(), present.end());
            present.erase(std::unique(present.begin(), present.end()), present.end());
            double bestCost = 0;
            int bestCorner = -1, bestScore = 1 << 30;
            bool bestKeeps = false, bestSimple = false;
            int bestTier = -1;
            std::int32_t bestMat = 0;
            for (int c = 0; c < 8; ++c) {
                const int pi = i + (c & 1), pj = j + (c >> 1 & 1), pk = k + (c >> 2 & 1);
                const bool border = isBorder(pi, pj, pk);
                if (flips[v.point[c]] >= kMaxFlipsPerPoint) continue;
                const Vec3 x = g.point(pi, pj, pk);
                for (std::int32_t t : present) {
                    if (t == v.mat[c] || (border && t != 0)) continue;
                    auto trial = v.mat;
                    trial[c] = t;
                    // a flip mends the block when fewer materials (or their
                    // complements) are split in it, or fewer are bad at all
                    const int score = badness(trial);
                    if (score >= badNow && badMaterials(trial) >= badMaterialsNow) continue;
                    const std::int32_t judged = t != 0 ? t : v.mat[c];
                    const double cost = std::abs(domain.value(judged, x));
                    // Among flips that mend the block, prefer those that keep
                    // the topology of the surface marching cubes draws
                    // (simpleFlip), then those that mend it most, then those
                    // that keep every region's Euler characteristic, then the
                    // one nearest the surface.
                    const int tier = plain ? 0 : flipTier(labels, ids, pi, pj, pk, v.mat[c], t, marchingCubes);
                    const bool simple = tier == (marchingCubes ? 3 : 2);
                    const bool keepsEuler = (v.mat[c] == 0 || eulerChange(labels, pi, pj, pk, v.mat[c], false) == 0) &&
                                            (t == 0 || eulerChange(labels, pi, pj, pk, t, true) == 0);
                    const bool better =
                        bestCorner < 0 || tier > bestTier ||
                        (tier == bestTier &&
                         (score < bestScore || (score == bestScore && keepsEuler > bestKeeps) ||
                          (score == bestScore && keepsEuler == bestKeeps && cost < bestCost)));
                    if (better) {
                        bestScore = score;
                        bestKeeps = keepsEuler;
                        bestSimple = simple;
                        bestTier = tier;
                        bestCost = cost;
                        bestCorner = c;
                        bestMat = t;
                    }
                }
            }
            // No single flip keeps the topology (a pocket or a speck of one
            // point touching another along an edge): move it first. A
            // 6-neighbour y of corner c that has the material c is to take
            // takes c's material (simple), then c flips (simple); e.g. a
            // one-point pocket of the outside steps away from the pocket it
            // touches instead of being filled.
            std::size_t prepPoint = 0;
            std::int32_t prepMat = 0;
            bool prep = false;
            if (!bestSimple && !plain) {
                double bestMove = 0;
                for (int c = 0; c < 8; ++c) {
                    const int pi = i + (c & 1), pj = j + (c >> 1 & 1), pk = k + (c >> 2 & 1);
                    if (flips[v.point[c]] >= kMaxFlipsPerPoint) continue;
                    const std::int32_t from = v.mat[c];
                    for (std::int32_t t : present) {
                        if (t == from || (isBorder(pi, pj, pk) && t != 0)) continue;
                        for (int d = 0; d < 6; ++d) {
                            const int yi = pi + (d == 0) - (d == 1), yj = pj + (d == 2) - (d == 3),
                                      yk = pk + (d == 4) - (d == 5);
                            if (yi < 0 || yj < 0 || yk < 0 || yi >= nx || yj >= ny || yk >= nz) continue;
                            if (from != 0 && isBorder(yi, yj, yk)) continue;
                            const std::size_t y = g.index(yi, yj, yk);
                            if (labels.material[y] != t || flips[y] >= kMaxFlipsPerPoint) continue;
                            if (!simpleFlip(labels, ids, yi, yj, yk, t, from, marchingCubes)) continue;
                            const std::int32_t keepId = ids.id[y];
                            const std::size_t keepRegions = ids.regions.size();
                            flipPoint(labels, ids, y, from);
                            const BlockView w = block(labels, i, j, k);
                            auto trial = w.mat;
                            trial[c] = t;
                            const bool ok = badness(trial) < badNow && simpleFlip(labels, ids, pi, pj, pk, from, t, marchingCubes);
                            labels.material[y] = t;  // undo (y's new neighbours were one region: no merge)
                            ids.id[y] = keepId;
                            ids.regions.truncate(keepRegions);
                            if (!ok) continue;
                            const double cost = std::abs(domain.value(t != 0 ? t : from, g.point(pi, pj, pk))) +
                                                std::abs(domain.value(from != 0 ? from : t, g.point(yi, yj, yk)));
                            if (!prep || cost < bestMove) {
                                prep = true;
                                bestMove = cost;
                                prepPoint = y;
                                prepMat = from;
                                bestCorner = c;
                                bestMat = t;
                            }
                        }
                    }
                }
            }
            if (prep) {
                record(prepPoint, prepMat);
                touched.insert(prepPoint);
            }
            if (bestCorner < 0) {
                // No single flip makes this block better (e.g. a checkerboard):
                // grow the first bad material by its cheapest neighbour point.
                // Growing is monotone, so repeated rounds cannot cycle.
                std::int32_t grow = 0;
                for (int c = 0; c < 8 && grow == 0; ++c) {
                    unsigned p = 0;
                    for (int d = 0; d < 8; ++d)
                        if (v.mat[d] == v.mat[c]) p |= 1u << d;
                    if (v.mat[c] != 0 && !kTable.ok[p]) grow = v.mat[c];
                }
                if (grow == 0) continue;
                for (int c = 0; c < 8; ++c) {
                    if (v.mat[c] == grow) continue;
                    const int pi = i + (c & 1), pj = j + (c >> 1 & 1), pk = k + (c >> 2 & 1);
                    if (isBorder(pi, pj, pk)) continue;
                    const double cost = std::abs(domain.value(grow, g.point(pi, pj, pk)));
                    if (bestCorner < 0 || cost < bestCost) {
                        bestCorner = c;
                        bestCost = cost;
                        bestMat = grow;
                    }
                }
                if (bestCorner < 0) continue;
            }
            const std::size_t p = v.point[bestCorner];
            record(p, bestMat);
            touched.insert(p);
        }
        for (std::size_t p : touched) {
            const int i = static_cast<int>(p % nx), j = static_cast<int>(p / nx % ny), k = static_cast<int>(p / nx / ny);
            for (int c = 0; c < 8; ++c) {
                const int bi = i - (c & 1), bj = j - (c >> 1 & 1), bk = k - (c >> 2 & 1);
                if (bi >= 0 && bj >= 0 && bk >= 0) bad.push_back(g.index(bi, bj, bk));
            }
        }
        if (touched.empty() && !plain) {
            // The topology preference can spend points' flips going back and
            // forth (random labellings of several materials): from here on,
            // the plain rules with fresh flips.
            plain = true;
            std::fill(flips.begin(), flips.end(), 0);
            continue;
        }
        if (touched.empty())
            throw Error("non-manifold repair is stuck: " + std::to_string(bad.size()) +
                        " places where regions touch along an edge or at a point cannot be fixed by flipping grid "
                        "points; try a different --size");
    }
}

std::vector<RegionTopology> regionTopology(const Labels& l) {
    const auto [nx, ny, nz] = l.grid.dims;
    // Every point pair, square and block is counted at the block whose lowest
    // corner is its lowest point; the grid's outer layer is background, so
    // nothing mixed is lost past the last block. Uniform blocks (almost all)
    // are skipped after one look at their corners.
    struct Acc {
        std::map<std::int32_t, RegionTopology> t;
        std::vector<std::pair<std::int32_t, std::size_t>> mixed;  // (material, block)
    };
    tbb::enumerable_thread_specific<Acc> local;
    tbb::parallel_for(tbb::blocked_range<int>(0, std::max(nz - 1, 0)), [&](const tbb::blocked_range<int>& r) {
        Acc& acc = local.local();
        auto addEuler = [&](std::int32_t m, long long d) {
            if (m == 0) return;
            auto& t = acc.t[m];
            t.material = m;
            t.euler += d;
        };
        // squares and blocks: each material present but not everywhere counts once
        auto mixedSet = [&](const std::int32_t* m, int n, long long d, std::size_t block) {
            for (int c = 0; c < n; ++c) {
                if (m[c] == 0) continue;
                bool first = true, all = true;
                for (int e = 0; e < c; ++e) first = first && m[e] != m[c];
                for (int e = 0; e < n; ++e) all = all && m[e] == m[c];
                if (!first || all) continue;
                addEuler(m[c], d);
                if (block != static_cast<std::size_t>(-1)) acc.mixed.emplace_back(m[c], block);
            }
        };
        for (int k = r.begin(); k != r.end(); ++k)
            for (int j = 0; j + 1 < ny; ++j)
                for (int i = 0; i + 1 < nx; ++i) {
                    const BlockView b = block(l, i, j, k);
                    bool uniform = true;
                    for (int c = 1; c < 8; ++c) uniform = uniform && b.mat[c] == b.mat[0];
                    if (uniform) continue;
                    // corner c of the block is offset (c & 1, c >> 1 & 1, c >> 2 & 1)
                    for (int d = 0; d < 3; ++d) {  // faces: pairs from the lowest corner
                        const std::int32_t a = b.mat[0], o = b.mat[1 << d];
                        if (a != o) {
                            addEuler(a, 1);
                            addEuler(o, 1);
                        }
                    }
                    const std::int32_t sq[3][4] = {{b.mat[0], b.mat[1], b.mat[2], b.mat[3]},   // xy
                                                   {b.mat[0], b.mat[1], b.mat[4], b.mat[5]},   // xz
                                                   {b.mat[0], b.mat[2], b.mat[4], b.mat[6]}};  // yz
                    for (const auto& q : sq) mixedSet(q, 4, -1, static_cast<std::size_t>(-1));
                    mixedSet(b.mat.data(), 8, 1, l.grid.index(i, j, k));
                }
    });
    std::map<std::int32_t, RegionTopology> out;
    for (std::int32_t m : l.material)
        if (m != 0) {
            auto& t = out[m];
            t.material = m;
            ++t.points;
        }
    std::vector<std::pair<std::int32_t, std::size_t>> mixed;
    for (auto& acc : local) {
        for (auto& [m, t] : acc.t) {
            out[m].material = m;
            out[m].euler += t.euler;
        }
        mixed.insert(mixed.end(), acc.mixed.begin(), acc.mixed.end());
    }
    std::sort(mixed.begin(), mixed.end());
    DisjointSets<std::size_t> sets(mixed.size());
    for (std::size_t n = 0; n < mixed.size(); ++n) {
        const auto [m, b] = mixed[n];
        const int i = static_cast<int>(b % nx), j = static_cast<int>(b / nx % ny), k = static_cast<int>(b / nx / ny);
        // neighbour block in +d shares the square of the block's far face in d
        for (int d = 0; d < 3; ++d) {
            const int ni = i + (d == 0), nj = j + (d == 1), nk = k + (d == 2);
            if (ni + 1 >= nx || nj + 1 >= ny || nk + 1 >= nz) continue;
            bool present = false, all = true;
            for (int c = 0; c < 8; ++c) {
                if (!(c >> d & 1)) continue;
                const std::int32_t mm = l.material[l.grid.index(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))];
                present = present || mm == m;
                all = all && mm == m;
            }
            if (!present || all) continue;
            const auto it = std::lower_bound(mixed.begin(), mixed.end(), std::make_pair(m, l.grid.index(ni, nj, nk)));
            if (it == mixed.end() || it->first != m) continue;
            const std::size_t other = static_cast<std::size_t>(it - mixed.begin());
            sets.unite(n, other);
        }
    }
    for (std::size_t n = 0; n < mixed.size(); ++n)
        if (sets.isRoot(n)) ++out[mixed[n].first].components;
    std::vector<RegionTopology> v;
    for (auto& [m, t] : out) v.push_back(t);
    return v;
}

std::string describe(const std::vector<RegionTopology>& t) {
    std::ostringstream s;
    for (std::size_t i = 0; i < t.size(); ++i) {
        if (i) s << "; ";
        s << "material " << t[i].material << ": " << t[i].components << " surface component"
          << (t[i].components == 1 ? "" : "s") << ", Euler characteristic " << t[i].euler;
    }
    return s.str();
}

std::size_t fillOneCellPits(Labels& labels) {
    const auto [nx, ny, nz] = labels.grid.dims;
    if (nx < 3 || ny < 3 || nz < 3) return 0;
    auto& mat = labels.material;
    const std::ptrdiff_t sx = static_cast<std::ptrdiff_t>(labels.grid.index(1, 0, 0) - labels.grid.index(0, 0, 0));
    const std::ptrdiff_t sy = static_cast<std::ptrdiff_t>(labels.grid.index(0, 1, 0) - labels.grid.index(0, 0, 0));
    const std::ptrdiff_t sz = static_cast<std::ptrdiff_t>(labels.grid.index(0, 0, 1) - labels.grid.index(0, 0, 0));
    const std::array<std::ptrdiff_t, 6> step{-sx, sx, -sy, sy, -sz, sz};
    auto interior = [&](std::size_t q) {
        const auto i = static_cast<int>(q % static_cast<std::size_t>(nx));
        const auto j = static_cast<int>(q / static_cast<std::size_t>(nx) % static_cast<std::size_t>(ny));
        const auto k = static_cast<int>(q / (static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny)));
        return i > 0 && j > 0 && k > 0 && i + 1 < nx && j + 1 < ny && k + 1 < nz;
    };
    // Material a pit would join (0: not a pit); `open` gets the face
    // neighbour through which it opens.
    auto pitMaterial = [&](std::size_t q, std::size_t* open) -> std::int32_t {
        if (mat[q] != 0 || !interior(q)) return 0;
        std::int32_t m = 0;
        int count = 0, background = 0;
        for (int d = 0; d < 6; ++d) {
            const std::size_t n = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(q) + step[d]);
            const std::int32_t b = mat[n];
            if (b == 0) {
                ++background;
                if (open) *open = n;
            } else if (m == 0 || b == m) {
                m = b;
                ++count;
            }
        }
        return count == 5 && background == 1 ? m : 0;
    };
    std::vector<std::size_t> candidates;
    {
        // first pass: the whole grid, slab by slab in parallel, in index order
        std::vector<std::vector<std::size_t>> perSlab(static_cast<std::size_t>(nz));
        tbb::parallel_for(tbb::blocked_range<int>(1, nz - 1), [&](const auto& r) {
            for (int k = r.begin(); k != r.end(); ++k)
                for (int j = 1; j + 1 < ny; ++j)
                    for (int i = 1; i + 1 < nx; ++i) {
                        const std::size_t q = labels.grid.index(i, j, k);
                        if (pitMaterial(q, nullptr) != 0) perSlab[static_cast<std::size_t>(k)].push_back(q);
                    }
        });
        for (auto& v : perSlab) candidates.insert(candidates.end(), v.begin(), v.end());
    }
    std::size_t filled = 0;
    std::vector<std::size_t> fill;
    std::vector<std::int32_t> to;
    while (!candidates.empty()) {
        std::sort(candidates.begin(), candidates.end());
        candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
        fill.clear();
        to.clear();
        for (std::size_t q : candidates) {
            std::size_t open = 0;
            const std::int32_t m = pitMaterial(q, &open);
            // two pits opening into each other are a closed two-point cavity
            if (m != 0 && pitMaterial(open, nullptr) == 0) {
                fill.push_back(q);
                to.push_back(m);
            }
        }
        for (std::size_t t = 0; t < fill.size(); ++t) mat[fill[t]] = to[t];
        filled += fill.size();
        // only the background neighbours of what was filled can have become pits
        candidates.clear();
        for (std::size_t q : fill)
            for (int d = 0; d < 6; ++d) {
                const std::size_t n = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(q) + step[d]);
                if (pitMaterial(n, nullptr) != 0) candidates.push_back(n);
            }
    }
    return filled;
}

}  // namespace isohex::octree

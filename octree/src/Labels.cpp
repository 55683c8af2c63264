// Grid labelling, non-manifold repair and region topology.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <tuple>
#include <functional>
#include <set>
#include <unordered_map>
#include <unordered_set>
#include <sstream>
#include <random>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"
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

// The contributions of a non-uniform block to the Euler characteristic of
// each material's boundary (the union of the closed cubes around its
// points), with every point pair, square and block counted at the block
// whose lowest corner is its lowest point: add(material, delta, wholeBlock)
// for the lowest corner's three pairs (+1 for each material of a pair that
// differs), its three squares there and the block itself (-1 and +1 for each
// material present but not everywhere; wholeBlock for the block's own).
// Background (0) gets nothing.
template <class Add>
void forBlockEuler(const std::array<std::int32_t, 8>& mat, Add add) {
    // corner c of the block is offset (c & 1, c >> 1 & 1, c >> 2 & 1)
    for (int d = 0; d < 3; ++d) {
        const std::int32_t a = mat[0], o = mat[1 << d];
        if (a == o) continue;
        if (a != 0) add(a, 1, false);
        if (o != 0) add(o, 1, false);
    }
    auto mixed = [&](const std::int32_t* m, int n, int d, bool wholeBlock) {
        for (int c = 0; c < n; ++c) {
            if (m[c] == 0) continue;
            bool first = true, all = true;
            for (int e = 0; e < c; ++e) first = first && m[e] != m[c];
            for (int e = 0; e < n; ++e) all = all && m[e] == m[c];
            if (first && !all) add(m[c], d, wholeBlock);
        }
    };
    const std::int32_t sq[3][4] = {{mat[0], mat[1], mat[2], mat[3]},   // xy
                                   {mat[0], mat[1], mat[4], mat[5]},   // xz
                                   {mat[0], mat[2], mat[4], mat[6]}};  // yz
    for (const auto& q : sq) mixed(q, 4, -1, false);
    mixed(mat.data(), 8, 1, true);
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

// What mcLocal computes for one state of a window.
struct McLocal {
    long long chi = 0;
    int closed = 0;                        // pieces without a port
    std::vector<std::int32_t> portGroup;   // per vertex: first port of its piece (-1: not a port)
};

// Pattern of a cell as the polygoniser uses it: its signs, inverted when its
// ambiguous face meets the opposite ambiguous face of its neighbour.
inline std::uint8_t correctedSigns(std::uint8_t raw, std::uint8_t neighbourRaw, const CellEdgeGroups& t) {
    static constexpr std::uint8_t kOpposite[7] = {0, 3, 4, 1, 2, 6, 5};
    const std::uint8_t f = t.ambiguousFace[raw];
    return f != 0 && t.ambiguousFace[neighbourRaw] == kOpposite[f] ? static_cast<std::uint8_t>(~raw) : raw;
}

// The window of mcLocal around a box of changed points k[a] points wide on
// axis a: 4 more points on every side (a single point: 9x9x9). Relative to
// the box's lowest point (offset 0, window point 4), points at offsets -4..k+3.
struct McBox {
    std::array<int, 3> k{1, 1, 1};
    int w(int a) const { return k[a] + 8; }
    int points() const { return w(0) * w(1) * w(2); }
};

// in: the window's points (x fastest), true when inside. A change of the
// points in the box changes the raw patterns of the cells with a corner in it
// (offsets -1..k-1) and, through the ambiguous faces, the corrected patterns
// of the cells one further (-2..k): those are R. The faces that can change
// are the grid edges with both ends within -2..k+1.
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

using PointChange = std::pair<std::size_t, std::int32_t>;  // grid index, new material

// The window of box `b` whose box starts at grid point lo: 1 where the
// point has material m (points off the grid: 0).
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

// Whether giving the points of `changes` their new materials keeps the
// components and Euler characteristic of the polygoniser's surface of
// material m (m's points inside, every other point outside).
// (eulerChange: the change of the surface's Euler characteristic, exact.)
bool mcKeeps(const Labels& l, const std::vector<PointChange>& changes, std::int32_t m, const CellEdgeGroups& t,
             long long* eulerChange = nullptr) {
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

// The polygon surface of material m in a fixed window (the box lo..hi of
// grid points that may change, and 4 points around it), compared with the
// window as it was when the probe was made: 0 when every change made since
// inside the box keeps the surface's components and Euler characteristic
// (as mcKeeps decides it), otherwise a count that grows with the difference
// (the Euler change, pieces without a port gained or lost, pieces joining
// or splitting ports). The deep search's measure.
class McProbe {
public:
    McProbe(const Labels& l, std::array<int, 3> lo, std::array<int, 3> hi, std::int32_t m, const CellEdgeGroups& t)
        : l_(l), lo_(lo), m_(m), t_(t) {
        for (int a = 0; a < 3; ++a) box_.k[a] = hi[a] - lo[a] + 1;
        fillWindow(l_, lo_, box_, m_, in_);
        mcLocal(in_, box_, t_, before_);
        beforeGroups_ = groups(before_);
    }
    long long distance() {
        fillWindow(l_, lo_, box_, m_, in_);
        mcLocal(in_, box_, t_, after_);
        long long d = std::abs(after_.chi - before_.chi) + std::abs(after_.closed - before_.closed);
        if (after_.portGroup != before_.portGroup) {
            const long long ga = groups(after_);
            d += ga == beforeGroups_ ? 1 : std::abs(ga - beforeGroups_);
        }
        return d;
    }

private:
    static long long groups(const McLocal& s) {
        long long n = 0;
        for (std::size_t v = 0; v < s.portGroup.size(); ++v) n += s.portGroup[v] == static_cast<std::int32_t>(v);
        return n;
    }
    const Labels& l_;
    std::array<int, 3> lo_;
    std::int32_t m_;
    const CellEdgeGroups& t_;
    McBox box_;
    std::vector<std::uint8_t> in_;
    McLocal before_, after_;
    long long beforeGroups_ = 0;
};

bool mcKeeps(const Labels& l, int i, int j, int k, std::int32_t m, const CellEdgeGroups& t,
             long long* eulerChange = nullptr) {
    const std::size_t p = l.grid.index(i, j, k);
    const std::int32_t to = l.material[p] == m ? m + 1 : m;  // toggles m there (any other material is outside m)
    return mcKeeps(l, {PointChange{p, to}}, m, t, eulerChange);
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
            throw SettingError({"non-manifold repair found no fixpoint after " + std::to_string(kMaxRounds) +
                                    " rounds (" + std::to_string(bad.size()) + " bad places left); try a different ",
                                Setting::Size, " or ", Setting::Iso});
        std::set<std::size_t> touched;  // points changed this round; their blocks wait for the next round
        std::vector<std::size_t> unionOnly;  // blocks with no flip to try where only the union is bad
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
                if (grow == 0) {
                    unionOnly.push_back(b);
                    continue;
                }
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
        if (touched.empty() && plain) {
            // Last resort, where nothing else is left: every material is fine
            // on its own in these blocks but their union is not (points of
            // two materials touching along an edge or at a vertex with the
            // outside around them), and the points have used up their flips
            // trading places (the JHU atlas with --smooth 0.5 to 1.5 stopped
            // here). The outside grows: in each block the point nearest its
            // surface leaves, whatever its flips. Only reached when no other
            // rule changes anything (in plain mode; the topology preference
            // first gives way below); kMaxRounds still bounds the loop.
            for (std::size_t b : unionOnly) {
                const auto [i, j, k] = g.coords(b);
                const BlockView v = block(labels, i, j, k);
                bool stale = false;
                for (std::size_t q : v.point) stale = stale || touched.count(q);
                if (stale || blockManifold(v.mat)) continue;
                int best = -1;
                double bestCost = 0;
                for (int c = 0; c < 8; ++c) {
                    if (v.mat[c] == 0) continue;
                    const double cost =
                        std::abs(domain.value(v.mat[c], g.point(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))));
                    if (best < 0 || cost < bestCost) {
                        best = c;
                        bestCost = cost;
                    }
                }
                if (best < 0) continue;
                record(v.point[best], 0);
                touched.insert(v.point[best]);
            }
        }
        for (std::size_t p : touched) {
            const auto [i, j, k] = g.coords(p);
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
            throw SettingError({"non-manifold repair is stuck: " + std::to_string(bad.size()) +
                                    " places where regions touch along an edge or at a point cannot be fixed by "
                                    "flipping grid points; try a different ",
                                Setting::Size});
    }
}

namespace {

// Euler characteristic of the boundary of the union of the cubes around
// every material's points (regionTopology's sum), counted over the blocks
// with lowest corners `blocks`.
long long cubeEuler(const Labels& l, const std::vector<std::size_t>& blocks) {
    long long chi = 0;
    for (std::size_t b : blocks) {
        const auto [i, j, k] = l.grid.coords(b);
        const BlockView v = block(l, i, j, k);
        if (!uniformBlock(v.mat)) forBlockEuler(v.mat, [&](std::int32_t, int d, bool) { chi += d; });
    }
    return chi;
}

// matchPolygonTopology's search: at most this many flips on top of the
// repair's change, and this many trials per search (a bound on the time a
// noisy place can take: three flips among 80 options are 82,160 trials).
constexpr int kMatchDepth = 3;
constexpr std::size_t kMatchTrials = 150'000;
// The deep search (for what the flip search cannot mend): flips of boundary
// points within kDeepReach of the group, kDeepBeam sets kept per round, at
// most kDeepDepth flips and kDeepTrials trials; a unit of topology distance
// weighs as much as kDeepTopologyWeight bad blocks; a beam stops after
// kDeepPatience rounds without a better best score.
constexpr int kDeepReach = 2;
constexpr std::size_t kDeepBeam = 12;
constexpr int kDeepDepth = 10;
constexpr std::size_t kDeepTrials = 40'000;
constexpr long long kDeepTopologyWeight = 4;
constexpr int kDeepPatience = 2;
// The annealing after a beam that found nothing: up to kAnnealChains chains
// of kAnnealSteps steps, the temperature falling from kAnnealT0 to kAnnealT1
// (in units of the deep search's score), each option on costing
// kAnnealOptionCost; at most kAnnealBudget steps in one run.
constexpr int kAnnealChains = 6;
constexpr long kAnnealSteps = 10'000;
constexpr double kAnnealT0 = 1.5, kAnnealT1 = 0.5, kAnnealOptionCost = 2;
constexpr std::size_t kAnnealBudget = 120'000;

// Lowest corners of the blocks holding any of the points, sorted, unique (into out).
void blocksAround(const Grid& g, const std::vector<std::size_t>& points, std::vector<std::size_t>& out) {
    const auto [nx, ny, nz] = g.dims;
    out.clear();
    for (std::size_t p : points) {
        const auto [i, j, k] = g.coords(p);
        for (int c = 0; c < 8; ++c) {
            const int bi = i - (c & 1), bj = j - (c >> 1 & 1), bk = k - (c >> 2 & 1);
            if (bi >= 0 && bj >= 0 && bk >= 0 && bi + 1 < nx && bj + 1 < ny && bk + 1 < nz)
                out.push_back(g.index(bi, bj, bk));
        }
    }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
}

std::vector<std::size_t> blocksAround(const Grid& g, const std::vector<std::size_t>& points) {
    std::vector<std::size_t> out;
    blocksAround(g, points, out);
    return out;
}

// Whether the change keeps every involved material's polygoniser surface;
// *eulerChange: the sum of their Euler changes.
bool changeKeepsPolygonTopology(const Labels& l, const std::vector<PointChange>& changes, const CellEdgeGroups& t,
                                long long* eulerChange) {
    std::vector<std::int32_t> mats;
    for (const auto& [p, to] : changes) {
        if (l.material[p] == to) continue;
        if (l.material[p] != 0) mats.push_back(l.material[p]);
        if (to != 0) mats.push_back(to);
    }
    std::sort(mats.begin(), mats.end());
    mats.erase(std::unique(mats.begin(), mats.end()), mats.end());
    bool keeps = true;
    long long sum = 0;
    for (std::int32_t m : mats) {
        long long d = 0;
        keeps = mcKeeps(l, changes, m, t, &d) && keeps;
        sum += d;
    }
    if (eulerChange) *eulerChange = sum;
    return keeps;
}

}  // namespace

TopologyMatchReport matchPolygonTopology(Labels& repaired, const Labels& sampled, const Domain& domain,
                                         const CellEdgeGroups& table) {
    TopologyMatchReport rep;
    const Grid& g = repaired.grid;
    const auto [nx, ny, nz] = g.dims;
    if (sampled.material.size() != repaired.material.size())
        throw Error("matchPolygonTopology: the sampled and repaired labels have different grids");
    std::vector<std::size_t> changed;
    for (std::size_t p = 0; p < repaired.material.size(); ++p)
        if (repaired.material[p] != sampled.material[p]) changed.push_back(p);
    if (changed.empty()) return rep;
    auto coords = [&](std::size_t p) { return g.coords(p); };
    // Groups: changed points within kGap of each other on every axis. A
    // group's search flips points within 1 of it, or within 2 where no
    // point of another group is next to the flip; so a block holding a flip
    // holds no point of another group, and a block holding flips of two
    // groups is checked by the later group's search.
    constexpr int kGap = 2;
    std::unordered_map<std::size_t, std::int32_t> at;
    at.reserve(changed.size() * 2);
    for (std::size_t n = 0; n < changed.size(); ++n) at.emplace(changed[n], static_cast<std::int32_t>(n));
    DisjointSets<std::int32_t> groups(changed.size());
    for (std::size_t n = 0; n < changed.size(); ++n) {
        const auto [i, j, k] = coords(changed[n]);
        for (int dz = -kGap; dz <= kGap; ++dz)
            for (int dy = -kGap; dy <= kGap; ++dy)
                for (int dx = -kGap; dx <= kGap; ++dx) {
                    const int x = i + dx, y = j + dy, z = k + dz;
                    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
                    const auto it = at.find(g.index(x, y, z));
                    if (it != at.end() && it->second > static_cast<std::int32_t>(n))
                        groups.unite(static_cast<std::int32_t>(n), it->second);
                }
    }
    std::map<std::int32_t, std::vector<std::size_t>> members;  // by root: the smallest member, in grid order
    for (std::size_t n = 0; n < changed.size(); ++n)
        members[groups.find(static_cast<std::int32_t>(n))].push_back(changed[n]);
    rep.groups = members.size();

    Labels work = sampled;
    auto isBorder = [&](const std::array<int, 3>& c) {
        return c[0] == 0 || c[1] == 0 || c[2] == 0 || c[0] == nx - 1 || c[1] == ny - 1 || c[2] == nz - 1;
    };
    auto apply = [&](const std::vector<PointChange>& ch) {
        for (const auto& [p, to] : ch) work.material[p] = to;
    };
    auto manifoldAt = [&](const std::vector<std::size_t>& blocks) {
        for (std::size_t b : blocks) {
            const auto [i, j, k] = g.coords(b);
            const BlockView v = block(work, i, j, k);
            if (!uniformBlock(v.mat) && !blockManifold(v.mat)) return false;
        }
        return true;
    };
    // The points within 1 of `points`, sorted.
    // Whether a changed point of another group lies within 1 of (x, y, z)
    // (not on the grid's border).
    auto nextToOtherGroup = [&](int x, int y, int z, std::int32_t group) {
        for (int q = 0; q < 27; ++q) {
            const auto it = at.find(g.index(x + q % 3 - 1, y + q / 3 % 3 - 1, z + q / 9 - 1));
            if (it != at.end() && groups.find(it->second) != group) return true;
        }
        return false;
    };
    auto around = [&](const std::vector<std::size_t>& points) {
        std::vector<std::size_t> near;
        for (std::size_t p : points) {
            const auto [i, j, k] = coords(p);
            for (int dz = -1; dz <= 1; ++dz)
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int x = i + dx, y = j + dy, z = k + dz;
                        if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
                        near.push_back(g.index(x, y, z));
                    }
        }
        std::sort(near.begin(), near.end());
        near.erase(std::unique(near.begin(), near.end()), near.end());
        return near;
    };
    constexpr int kMaxExtent = 12;   // wider groups are split, or keep the repair's change
    constexpr std::size_t kDeepOptions = 80;  // three flips only around small groups (options^3)

    // Search: up to kMatchDepth flips of points within 1 of the group, on top
    // of the repair's change (already applied), that leave every block around
    // them manifold and make the whole change (from `before`) keep the
    // polygoniser's surface. Applies the best one; false if none.
    // later/laterBefore (optional): points still to be changed after this
    // one, as the repair changes them and as they are now; the blocks are
    // judged with them changed, the surface with them as they are.
    auto search = [&](std::int32_t group, const std::vector<std::size_t>& near, const std::vector<PointChange>& before,
                      const std::vector<PointChange>& change, long long d0,
                      const std::vector<PointChange>* later = nullptr,
                      const std::vector<PointChange>* laterBefore = nullptr,
                      const std::unordered_set<std::size_t>* frozen = nullptr, int maxDepth = kMatchDepth) {
        // of the later points, those a block around a flip can hold (within
        // 1 of `near`): set and reset on every trial
        std::vector<PointChange> laterHere, laterHereBefore;
        if (later) {
            const std::vector<std::size_t> reach = around(near);
            for (std::size_t n = 0; n < later->size(); ++n)
                if (std::binary_search(reach.begin(), reach.end(), (*later)[n].first)) {
                    laterHere.push_back((*later)[n]);
                    laterHereBefore.push_back((*laterBefore)[n]);
                }
        }
        std::vector<PointChange> options;  // (point, material it may take)
        for (std::size_t p : near) {
            const auto c = coords(p);
            if (isBorder(c) || (frozen && frozen->count(p))) continue;
            if (nextToOtherGroup(c[0], c[1], c[2], group)) continue;
            std::vector<std::int32_t> to{0, sampled.material[p], repaired.material[p]};
            for (int d = 0; d < 6; ++d) {
                const int x = c[0] + (d == 0) - (d == 1), y = c[1] + (d == 2) - (d == 3), z = c[2] + (d == 4) - (d == 5);
                to.push_back(work.material[g.index(x, y, z)]);
            }
            std::sort(to.begin(), to.end());
            to.erase(std::unique(to.begin(), to.end()), to.end());
            for (std::int32_t m : to)
                if (m != work.material[p]) options.emplace_back(p, m);
        }
        bool found = false;
        std::vector<PointChange> best;
        std::size_t bestDiff = 0;
        double bestCost = 0;
        std::vector<int> pick;
        std::vector<PointChange> flips, undo;  // reused by every trial
        std::vector<std::size_t> flipped, blocks;
        std::size_t trials = 0;
        auto evaluate = [&]() {
            ++trials;
            flips.clear();
            undo.clear();
            flipped.clear();
            for (int q : pick) {
                flips.push_back(options[q]);
                flipped.push_back(options[q].first);
                undo.emplace_back(options[q].first, work.material[options[q].first]);
            }
            blocksAround(g, flipped, blocks);
            apply(laterHere);
            apply(flips);
            // Where both states are manifold the polygoniser's surface changes
            // its Euler characteristic as the cubes' boundary does: a cheap
            // filter before the exact test.
            bool candidate = manifoldAt(blocks);
            if (candidate) {
                const long long chi = cubeEuler(work, blocks);
                apply(undo);
                candidate = chi - cubeEuler(work, blocks) == -d0;
                apply(flips);
            }
            apply(laterHereBefore);
            if (candidate) {
                std::vector<PointChange> total;
                for (const auto& [p, was] : before)
                    if (work.material[p] != was) total.emplace_back(p, work.material[p]);
                apply(before);
                const bool keeps = changeKeepsPolygonTopology(work, total, table, nullptr);
                apply(change);
                apply(flips);
                if (keeps) {
                    std::size_t diff = 0;
                    double cost = 0;
                    for (const auto& [p, to] : total) {
                        if (to == sampled.material[p]) continue;
                        ++diff;
                        const auto c = coords(p);
                        cost += std::abs(domain.value(to != 0 ? to : sampled.material[p], g.point(c[0], c[1], c[2])));
                    }
                    if (!found || diff < bestDiff || (diff == bestDiff && cost < bestCost)) {
                        found = true;
                        best = flips;
                        bestDiff = diff;
                        bestCost = cost;
                    }
                }
            }
            apply(undo);
        };
        for (int depth = 1; depth <= maxDepth && !found; ++depth) {
            if (depth == 3 && options.size() > kDeepOptions) break;
            pick.assign(depth, 0);
            // combinations of `depth` options at distinct points, in order
            std::function<void(int, int)> choose = [&](int level, int from) {
                if (trials >= kMatchTrials) return;
                if (level == depth) {
                    evaluate();
                    return;
                }
                for (int q = from; q < static_cast<int>(options.size()); ++q) {
                    bool clash = false;
                    for (int e = 0; e < level; ++e) clash = clash || options[pick[e]].first == options[q].first;
                    if (clash) continue;
                    pick[level] = q;
                    choose(level + 1, q + 1);
                }
            };
            choose(0, 0);
        }
        if (found) apply(best);
        return found;
    };

    // One group: its change as the repair made it when that keeps the
    // surface; else the search's. A group too wide for the search is taken
    // part by part (see below); it keeps the repair's change whole if its
    // parts leave a block around it bad.
    auto extentOf = [&](const std::vector<std::size_t>& points) {
        std::array<int, 3> lo{nx, ny, nz}, hi{-1, -1, -1};
        for (std::size_t p : points) {
            const auto c = coords(p);
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], c[a]);
                hi[a] = std::max(hi[a], c[a]);
            }
        }
        return std::array<int, 6>{lo[0], lo[1], lo[2], hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1};
    };
    auto place = [&](const std::vector<std::size_t>& points, long long d0) {
        const auto box = extentOf(points);
        TopologyMatchReport::Place pl;
        pl.lo = {box[0], box[1], box[2]};
        pl.hi = {box[0] + box[3] - 1, box[1] + box[4] - 1, box[2] + box[5] - 1};
        pl.points = points.size();
        pl.eulerChange = d0;
        rep.unmended.push_back(pl);
    };
    auto changeOf = [&](const std::vector<std::size_t>& points) {
        std::vector<PointChange> change;
        for (std::size_t p : points) change.emplace_back(p, repaired.material[p]);
        return change;
    };
    // Deep search, for a group (or part) the flip search could not mend: a
    // beam search over sets of flips of points within kDeepReach of it
    // (points on a material boundary, none next to another group or in
    // `frozen`), on top of the repair's change. A set is scored by how far
    // the polygon surface in a window around the box is from what it was
    // before the group (McProbe, per material) and by the blocks it leaves
    // bad. Each round extends the kDeepBeam best sets by one flip; the first
    // round with a set that leaves every block manifold and keeps the surface
    // (then checked again exactly, as in search) ends it, the set nearest the
    // sampled labels winning. A beam whose best score has not improved for
    // kDeepPatience rounds stops, as does one past kDeepDepth flips or
    // kDeepTrials probed sets. later/laterBefore as in search.
    // what the deep search flipped (point, material before), in order: its
    // box can reach beyond the points within 2 of the group
    std::vector<PointChange> deepFlipped;
    auto deepSearch = [&](std::int32_t group, const std::vector<std::size_t>& points,
                          const std::vector<PointChange>* later = nullptr,
                          const std::vector<PointChange>* laterBefore = nullptr,
                          const std::unordered_set<std::size_t>* frozen = nullptr) {
        const auto box = extentOf(points);
        std::array<int, 3> lo{}, hi{};
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::max(box[a] - kDeepReach, 1);
            hi[a] = std::min(box[a] + box[3 + a] - 1 + kDeepReach, g.dims[a] - 2);
        }
        // the box and 1 around it (the points its blocks hold), as they are
        // now (`after`, the group changed) and were before the group
        std::vector<PointChange> after;
        for (int z = lo[2] - 1; z <= hi[2] + 1; ++z)
            for (int y = lo[1] - 1; y <= hi[1] + 1; ++y)
                for (int x = lo[0] - 1; x <= hi[0] + 1; ++x) {
                    const std::size_t p = g.index(x, y, z);
                    after.emplace_back(p, work.material[p]);
                }
        std::vector<PointChange> before = after;
        {
            const std::unordered_set<std::size_t> inGroup(points.begin(), points.end());
            for (auto& [p, m] : before)
                if (inGroup.count(p)) m = sampled.material[p];
        }
        // Options: flips of points on a material boundary in the box, none
        // next to another group or in `frozen`; and moves that isolate a
        // one-point piece (speck or pocket) of the sampled labels: the point
        // takes its sampled material and its 26 neighbours that have that
        // material take the one most of its 6 neighbours have in the sampled
        // labels (no sequence of single flips reaches that without passing
        // through states that score worse); or the piece moved: a point
        // within 2 of it whose 26 neighbours all have one other material
        // takes its material (a piece of one point there is manifold). One
        // option is one step.
        auto allowed = [&](int x, int y, int z) {
            if (x < lo[0] || y < lo[1] || z < lo[2] || x > hi[0] || y > hi[1] || z > hi[2]) return false;
            return !(frozen && frozen->count(g.index(x, y, z))) && !nextToOtherGroup(x, y, z, group);
        };
        std::vector<std::vector<PointChange>> options;
        for (int z = lo[2]; z <= hi[2]; ++z)
            for (int y = lo[1]; y <= hi[1]; ++y)
                for (int x = lo[0]; x <= hi[0]; ++x) {
                    if (!allowed(x, y, z)) continue;
                    const std::size_t p = g.index(x, y, z);
                    bool boundary = false;
                    std::vector<std::int32_t> to{0, sampled.material[p], repaired.material[p]};
                    std::map<std::int32_t, int> sampled6;  // the sampled materials of the 6 neighbours
                    for (int q = 0; q < 27; ++q) {
                        const std::size_t o = g.index(x + q % 3 - 1, y + q / 3 % 3 - 1, z + q / 9 - 1);
                        boundary = boundary || work.material[o] != work.material[p];
                        if (q == 4 || q == 10 || q == 12 || q == 14 || q == 16 || q == 22) {
                            to.push_back(work.material[o]);
                            ++sampled6[sampled.material[o]];
                        }
                    }
                    if (boundary) {
                        std::sort(to.begin(), to.end());
                        to.erase(std::unique(to.begin(), to.end()), to.end());
                        for (std::int32_t m : to)
                            if (m != work.material[p]) options.push_back({PointChange{p, m}});
                    }
                    const std::int32_t m = sampled.material[p];
                    if (sampled6.count(m)) continue;  // not a one-point piece
                    std::int32_t around = 0;
                    int most = -1;
                    for (const auto& [mat, n] : sampled6)
                        if (n > most) {
                            most = n;
                            around = mat;
                        }
                    std::vector<PointChange> move;
                    if (work.material[p] != m) move.emplace_back(p, m);
                    bool ok = true;
                    for (int q = 0; q < 27 && ok; ++q) {
                        const int a = x + q % 3 - 1, b = y + q / 3 % 3 - 1, c = z + q / 9 - 1;
                        const std::size_t o = g.index(a, b, c);
                        if (q == 13 || work.material[o] != m) continue;
                        ok = allowed(a, b, c);
                        move.emplace_back(o, around);
                    }
                    if (ok && move.size() > 1) options.push_back(std::move(move));
                    // the piece moved
                    for (int q = 0; q < 125; ++q) {
                        const int a = x + q % 5 - 2, b = y + q / 5 % 5 - 2, c = z + q / 25 - 2;
                        if (!allowed(a, b, c) || work.material[g.index(a, b, c)] == m) continue;
                        bool interior = true;
                        const std::int32_t here = work.material[g.index(a, b, c)];
                        for (int r = 0; r < 27 && interior; ++r)
                            interior = work.material[g.index(a + r % 3 - 1, b + r / 3 % 3 - 1, c + r / 9 - 1)] == here;
                        if (interior) options.push_back({PointChange{g.index(a, b, c), m}});
                    }
                }
        // (a point can be offered twice, from two pieces: keep one)
        std::sort(options.begin(), options.end());
        options.erase(std::unique(options.begin(), options.end()), options.end());
        // The materials whose surface is judged: those the group's change or
        // an option gives or takes a point
        std::vector<std::int32_t> mats;
        for (std::size_t p : points) mats.insert(mats.end(), {sampled.material[p], repaired.material[p]});
        for (const auto& o : options)
            for (const auto& [p, to] : o) mats.insert(mats.end(), {work.material[p], to});
        std::sort(mats.begin(), mats.end());
        mats.erase(std::unique(mats.begin(), mats.end()), mats.end());
        apply(before);
        std::vector<std::unique_ptr<McProbe>> probes;
        for (std::int32_t m : mats)
            if (m != 0) probes.push_back(std::make_unique<McProbe>(work, lo, hi, m, table));
        apply(after);
        // Bad blocks are counted as the flips change them: the box's blocks
        // bad now, plus the change in the blocks around a set's flips. Later
        // parts of a wide group in the box are changed as the repair changes
        // them when blocks are judged, and left as they are for the surface.
        std::vector<PointChange> laterHere, laterHereBefore;
        if (later)
            for (std::size_t n = 0; n < later->size(); ++n) {
                const auto c = coords((*later)[n].first);
                bool in = true;
                for (int a = 0; a < 3; ++a) in = in && c[a] >= lo[a] - 1 && c[a] <= hi[a] + 1;
                if (!in) continue;
                laterHere.push_back((*later)[n]);
                laterHereBefore.push_back((*laterBefore)[n]);
            }
        auto isBad = [&](std::size_t b) {
            const auto [i, j, k] = g.coords(b);
            const BlockView v = block(work, i, j, k);
            return !uniformBlock(v.mat) && !blockManifold(v.mat);
        };
        std::vector<std::size_t> optionPoints(points);
        for (const auto& o : options)
            for (const auto& pc : o) optionPoints.push_back(pc.first);
        std::unordered_set<std::size_t> baseBad;
        apply(laterHere);
        for (std::size_t b : blocksAround(g, optionPoints))
            if (isBad(b)) baseBad.insert(b);
        apply(laterHereBefore);
        struct Trial {
            std::vector<int> pick;  // option indices, ascending
            long long score = 0;
            std::size_t diff = 0;   // points off the sampled labels that were not before
            double cost = 0;        // |field| at those
        };
        std::vector<std::size_t> flipped, blocks;
        std::vector<PointChange> undo;
        std::size_t trials = 0;
        // Scores t; false (not probed) when it has more bad blocks than
        // `threshold` (its score is at least that). goal: manifold and the
        // surface kept exactly.
        auto evaluate = [&](Trial& t, bool& goal, long long threshold) {
            goal = false;
            flipped.clear();
            undo.clear();
            for (int q : t.pick)
                for (const auto& [p, to] : options[q]) {
                    flipped.push_back(p);
                    undo.emplace_back(p, work.material[p]);
                    work.material[p] = to;
                }
            blocksAround(g, flipped, blocks);
            long long bad = static_cast<long long>(baseBad.size());
            apply(laterHere);
            for (std::size_t b : blocks) bad += static_cast<long long>(isBad(b)) - static_cast<long long>(baseBad.count(b));
            apply(laterHereBefore);
            if (bad > threshold) {
                apply(undo);
                return false;
            }
            ++trials;
            long long dist = 0;
            for (auto& pr : probes) dist += pr->distance();
            t.score = dist * kDeepTopologyWeight + bad;
            t.diff = 0;
            t.cost = 0;
            for (const auto& [p, was] : before) {
                const std::int32_t to = work.material[p];
                if (to == was || to == sampled.material[p]) continue;
                ++t.diff;
                const auto c = coords(p);
                t.cost += std::abs(domain.value(to != 0 ? to : sampled.material[p], g.point(c[0], c[1], c[2])));
            }
            if (dist == 0 && bad == 0) {
                std::vector<PointChange> total;
                for (const auto& [p, was] : before)
                    if (work.material[p] != was) total.emplace_back(p, work.material[p]);
                apply(before);
                goal = changeKeepsPolygonTopology(work, total, table, nullptr);
                apply(total);
            }
            apply(undo);
            return true;
        };
        // applies a winning set (recorded for the wide-group fallback)
        auto take = [&](const Trial& won) {
            for (int q : won.pick)
                for (const auto& [p, to] : options[q]) {
                    deepFlipped.emplace_back(p, work.material[p]);
                    work.material[p] = to;
                }
            rep.deepTrials += trials;
            return true;
        };
        auto ranks = [](const Trial& a, const Trial& b) {
            return std::tie(a.score, a.diff, a.cost, a.pick) < std::tie(b.score, b.diff, b.cost, b.pick);
        };
        std::vector<Trial> beam(1);
        std::set<std::vector<int>> seen;
        long long bestSoFar = std::numeric_limits<long long>::max();
        int lastGain = 0;
        for (int depth = 1; depth <= kDeepDepth && trials < kDeepTrials; ++depth) {
            std::vector<Trial> next, goals;
            std::multiset<long long> top;  // the kDeepBeam best scores of this round so far
            for (const Trial& from : beam)
                for (int q = 0; q < static_cast<int>(options.size()) && trials < kDeepTrials; ++q) {
                    bool clash = false;
                    for (int e : from.pick)
                        for (const auto& a : options[e])
                            for (const auto& b : options[q]) clash = clash || a.first == b.first;
                    if (clash) continue;
                    Trial t;
                    t.pick = from.pick;
                    t.pick.insert(std::upper_bound(t.pick.begin(), t.pick.end(), q), q);
                    if (!seen.insert(t.pick).second) continue;
                    bool goal = false;
                    const long long threshold =
                        top.size() < kDeepBeam ? std::numeric_limits<long long>::max() : *top.rbegin();
                    if (!evaluate(t, goal, threshold)) continue;
                    if (goal) {
                        goals.push_back(std::move(t));
                        continue;
                    }
                    top.insert(t.score);
                    if (top.size() > kDeepBeam) top.erase(std::prev(top.end()));
                    next.push_back(std::move(t));
                }
            if (!goals.empty()) {
                const Trial& best = *std::min_element(goals.begin(), goals.end(), [](const Trial& a, const Trial& b) {
                    return std::tie(a.diff, a.cost, a.pick) < std::tie(b.diff, b.cost, b.pick);
                });
                return take(best);
            }
            if (next.empty()) break;
            const long long bestNow = std::min_element(next.begin(), next.end(), ranks)->score;
            if (bestNow < bestSoFar) {
                bestSoFar = bestNow;
                lastGain = depth;
            } else if (depth - lastGain >= kDeepPatience) {
                break;
            }
            const std::size_t keep = std::min<std::size_t>(kDeepBeam, next.size());
            std::partial_sort(next.begin(), next.begin() + static_cast<std::ptrdiff_t>(keep), next.end(), ranks);
            next.resize(keep);
            beam = std::move(next);
        }
        // Annealing, when the beam found nothing: chains of random single
        // toggles of options (on or off), accepted by the Metropolis rule on
        // score + kAnnealOptionCost per option on, at a temperature falling
        // from kAnnealT0 to kAnnealT1; a chain that reaches a goal (checked
        // exactly) has its set shrunk (options dropped, one or two at a time,
        // while it stays a goal) and applied. Chains are seeded by their
        // number; the run's budget is spent in grid order, so the result
        // depends on the input only (not on the thread count).
        std::vector<std::vector<std::int32_t>> onWas(options.size());  // materials an option replaced
        std::unordered_map<std::size_t, int> takenBy;
        std::vector<std::vector<std::size_t>> blocksOf(options.size());  // the blocks around an option, when first drawn
        auto badIn = [&](const std::vector<std::size_t>& bs) {
            long long n = 0;
            apply(laterHere);
            for (std::size_t b2 : bs) n += isBad(b2);
            apply(laterHereBefore);
            return n;
        };
        auto toggle = [&](int q) {  // (switched on only when no point of it is taken)
            if (!onWas[q].empty()) {
                for (std::size_t n = 0; n < options[q].size(); ++n) {
                    work.material[options[q][n].first] = onWas[q][n];
                    takenBy.erase(options[q][n].first);
                }
                onWas[q].clear();
                return;
            }
            for (const auto& [p, to] : options[q]) {
                onWas[q].push_back(work.material[p]);
                takenBy.emplace(p, q);
                work.material[p] = to;
            }
        };
        for (int chain = 0; chain < kAnnealChains && !options.empty() && rep.annealSteps < kAnnealBudget; ++chain) {
            std::mt19937 rng(static_cast<std::uint32_t>(chain + 1));
            long long bad = static_cast<long long>(baseBad.size()), dist = 0;
            for (auto& pr : probes) dist += pr->distance();
            long long picks = 0;
            bool reached = false;
            Trial t;
            for (long step = 0; step < kAnnealSteps && rep.annealSteps < kAnnealBudget; ++step) {
                ++rep.annealSteps;
                const double T = kAnnealT0 * std::pow(kAnnealT1 / kAnnealT0, static_cast<double>(step) / static_cast<double>(kAnnealSteps));
                const int q = static_cast<int>(rng() % options.size());
                const bool wasOn = !onWas[q].empty();
                bool clash = false;
                for (const auto& pc : options[q]) clash = clash || (!wasOn && takenBy.count(pc.first) > 0);
                if (clash) continue;
                if (blocksOf[q].empty()) {
                    std::vector<std::size_t> pts;
                    for (const auto& pc : options[q]) pts.push_back(pc.first);
                    blocksAround(g, pts, blocksOf[q]);
                }
                const long long b0 = badIn(blocksOf[q]);
                toggle(q);
                const long long b1 = badIn(blocksOf[q]);
                long long d = 0;
                for (auto& pr : probes) d += pr->distance();
                const long long newBad = bad - b0 + b1, newPicks = picks + (wasOn ? -1 : 1);
                if (d == 0 && newBad == 0) {
                    // checked exactly from the state before the group; a set
                    // the probes pass but the exact test does not is kept
                    // and the chain goes on from it
                    t.pick.clear();
                    for (int o = 0; o < static_cast<int>(options.size()); ++o)
                        if (!onWas[o].empty()) t.pick.push_back(o);
                    for (int o : t.pick) toggle(o);
                    bool goal = false;
                    evaluate(t, goal, std::numeric_limits<long long>::max());
                    if (goal) {
                        reached = true;
                        break;
                    }
                    for (int o : t.pick) toggle(o);
                    bad = newBad;
                    dist = d;
                    picks = newPicks;
                    continue;
                }
                const double dE = static_cast<double>((d - dist) * kDeepTopologyWeight + (newBad - bad)) +
                                  kAnnealOptionCost * static_cast<double>(newPicks - picks);
                const std::uint32_t r = rng();
                if (dE <= 0 || static_cast<double>(r) < std::exp(-dE / T) * 4294967296.0) {
                    bad = newBad;
                    dist = d;
                    picks = newPicks;
                } else {
                    toggle(q);
                }
            }
            if (!reached) {
                for (int o = static_cast<int>(options.size()) - 1; o >= 0; --o)
                    if (!onWas[o].empty()) toggle(o);
                continue;
            }
            // t without options n (and n2 > n, if given); true, and t that
            // set, when it is still a goal
            auto dropped = [&](std::size_t n, std::size_t n2) {
                Trial u;
                u.pick = t.pick;
                if (n2 < u.pick.size()) u.pick.erase(u.pick.begin() + static_cast<std::ptrdiff_t>(n2));
                u.pick.erase(u.pick.begin() + static_cast<std::ptrdiff_t>(n));
                bool still = false;
                evaluate(u, still, 0);
                if (still) t = std::move(u);
                return still;
            };
            for (bool shrunk = true; shrunk;) {
                shrunk = false;
                for (std::size_t n = 0; n < t.pick.size();)
                    if (dropped(n, t.pick.size())) shrunk = true;
                    else ++n;
                for (std::size_t n = 0; n < t.pick.size() && !shrunk; ++n)
                    for (std::size_t n2 = n + 1; n2 < t.pick.size() && !shrunk; ++n2) shrunk = dropped(n, n2);
            }
            return take(t);
        }
        rep.deepTrials += trials;
        return false;
    };
    auto process = [&](std::int32_t group, const std::vector<std::size_t>& points) {
        deepFlipped.clear();
        const std::vector<PointChange> change = changeOf(points);
        const auto box = extentOf(points);
        const bool wide = std::max({box[3], box[4], box[5]}) > kMaxExtent;
        const std::vector<std::size_t> near = around(points), near2 = around(near);
        if (!wide) {
            long long d0 = 0;
            if (changeKeepsPolygonTopology(work, change, table, &d0)) {
                apply(change);
                return;
            }
            ++rep.groupsChanging;
            std::vector<PointChange> before;  // the state before the group, at the points it may touch
            for (std::size_t p : near2) before.emplace_back(p, work.material[p]);
            apply(change);
            // points next to the group first; then within 2, with two flips at most
            if (search(group, near, before, change, d0) ||
                search(group, near2, before, change, d0, nullptr, nullptr, nullptr, 2) ||
                deepSearch(group, points))
                ++rep.groupsMatched;
            else
                place(points, d0);
            return;
        }
        std::vector<PointChange> before;
        for (std::size_t p : near2) before.emplace_back(p, work.material[p]);
        // 26-connected parts of a wide group, in grid order
        std::unordered_map<std::size_t, std::int32_t> index;
        for (std::size_t n = 0; n < points.size(); ++n) index.emplace(points[n], static_cast<std::int32_t>(n));
        DisjointSets<std::int32_t> parts(points.size());
        for (std::size_t n = 0; n < points.size(); ++n) {
            const auto [i, j, k] = coords(points[n]);
            for (int q = 0; q < 27; ++q) {
                const int x = i + q % 3 - 1, y = j + q / 3 % 3 - 1, z = k + q / 9 - 1;
                if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
                const auto it = index.find(g.index(x, y, z));
                if (it != index.end()) parts.unite(static_cast<std::int32_t>(n), it->second);
            }
        }
        std::map<std::int32_t, std::vector<std::size_t>> byPart;
        for (std::size_t n = 0; n < points.size(); ++n) byPart[parts.find(static_cast<std::int32_t>(n))].push_back(points[n]);
        // The parts in turn, each checked from the state the earlier ones
        // left (so the group keeps the surface when every part does); a
        // part's search judges blocks with the later parts changed as the
        // repair changes them.
        // a part wider than the search is cut into boxes 8 points wide
        std::vector<std::vector<std::size_t>> order;
        for (const auto& [r, part] : byPart) {
            const auto pbox = extentOf(part);
            if (std::max({pbox[3], pbox[4], pbox[5]}) <= kMaxExtent) {
                order.push_back(part);
                continue;
            }
            std::map<std::array<int, 3>, std::vector<std::size_t>> chunks;
            for (std::size_t p : part) {
                const auto c = coords(p);
                chunks[{(c[2] - pbox[2]) / 8, (c[1] - pbox[1]) / 8, (c[0] - pbox[0]) / 8}].push_back(p);
            }
            for (auto& [key, chunk] : chunks) order.push_back(std::move(chunk));
        }
        const std::unordered_set<std::size_t> groupPoints(points.begin(), points.end());
        bool changing = false, mended = true;
        const std::size_t placesBefore = rep.unmended.size();
        for (std::size_t n = 0; n < order.size(); ++n) {
            const std::vector<std::size_t>& part = order[n];
            const std::vector<PointChange> partChange = changeOf(part);
            const std::vector<std::size_t> partNear = around(part), partNear2 = around(partNear);
            std::vector<PointChange> partBefore;
            for (std::size_t p : partNear2) partBefore.emplace_back(p, work.material[p]);
            long long dp = 0;
            const bool keeps = changeKeepsPolygonTopology(work, partChange, table, &dp);
            apply(partChange);
            if (keeps) continue;
            std::vector<PointChange> later, laterBefore;
            for (std::size_t m = n + 1; m < order.size(); ++m)
                for (std::size_t p : order[m]) {
                    later.emplace_back(p, repaired.material[p]);
                    laterBefore.emplace_back(p, work.material[p]);
                }
            std::unordered_set<std::size_t> frozen = groupPoints;  // the other parts' points
            for (std::size_t p : part) frozen.erase(p);
            changing = true;
            const bool found =
                search(group, partNear, partBefore, partChange, dp, &later, &laterBefore, &frozen) ||
                search(group, partNear2, partBefore, partChange, dp, &later, &laterBefore, &frozen, 2) ||
                deepSearch(group, part, &later, &laterBefore, &frozen);
            if (!found) place(part, dp);
            mended = mended && found;
        }
        if (changing) ++rep.groupsChanging;
        // the blocks around what changed (a flip is never next to another group)
        std::vector<std::size_t> touched = points;
        for (const auto& [p, was] : before)
            if (work.material[p] != was) touched.push_back(p);
        for (const auto& [p, was] : deepFlipped) touched.push_back(p);
        if (!manifoldAt(blocksAround(g, touched))) {
            // the whole group keeps the repair's change: one place for it
            for (auto it = deepFlipped.rbegin(); it != deepFlipped.rend(); ++it) work.material[it->first] = it->second;
            apply(before);
            long long d = 0;
            changeKeepsPolygonTopology(work, change, table, &d);
            apply(change);
            rep.unmended.resize(placesBefore);
            if (changing) place(points, d);
            mended = false;
        }
        if (changing && mended) ++rep.groupsMatched;
    };
    for (const auto& [root, points] : members) process(root, points);
    // Each search checked the blocks around its flips; the whole grid is
    // checked once more, and a result that is not manifold is not used.
    if (!badBlocks(work).empty()) {
        rep.groupsMatched = 0;
        rep.discarded = true;
        return rep;
    }
    std::size_t differ = 0;
    for (std::size_t p = 0; p < work.material.size(); ++p) differ += work.material[p] != repaired.material[p];
    rep.pointsChanged = differ;
    repaired.material = std::move(work.material);
    return rep;
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
        for (int k = r.begin(); k != r.end(); ++k)
            for (int j = 0; j + 1 < ny; ++j)
                for (int i = 0; i + 1 < nx; ++i) {
                    const BlockView b = block(l, i, j, k);
                    if (uniformBlock(b.mat)) continue;
                    forBlockEuler(b.mat, [&](std::int32_t m, int d, bool wholeBlock) {
                        auto& t = acc.t[m];
                        t.material = m;
                        t.euler += d;
                        if (wholeBlock) acc.mixed.emplace_back(m, l.grid.index(i, j, k));
                    });
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

namespace isohex::octree {

std::vector<PointEdit> editNearInvertedHexes(Labels& labels, const std::vector<std::array<double, 3>>& positions,
                                             const std::vector<std::size_t>& frozen, int maxSame) {
    const Grid& g = labels.grid;
    const auto [nx, ny, nz] = g.dims;
    std::vector<PointEdit> edits;
    if (nx < 3 || ny < 3 || nz < 3) return edits;
    auto& mat = labels.material;
    auto isFrozen = [&](std::size_t p) { return std::find(frozen.begin(), frozen.end(), p) != frozen.end(); };
    const int faceStep[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    // Whether point (i, j, k) leaving material `from` for `to` keeps the
    // components, tunnels and cavities of both (simple for each: its
    // neighbours of that material one 26-component, the rest one 6-component
    // in the 18-neighbourhood) and leaves the 8 blocks around it manifold.
    auto allowed = [&](int i, int j, int k, std::int32_t from, std::int32_t to) {
        std::array<std::int32_t, 27> m27;
        for (int q = 0; q < 27; ++q)
            m27[q] = mat[g.index(i + q % 3 - 1, j + q / 3 % 3 - 1, k + q / 9 - 1)];
        // simple for the set of points whose label passes `inSet`
        auto simple = [&](auto inSet) {
            std::array<bool, 27> in{}, out{};
            for (int q = 0; q < 27; ++q) {
                in[q] = q != 13 && inSet(m27[q]);
                out[q] = q != 13 && !inSet(m27[q]);
            }
            return topoNumber(in, 26) == 1 && topoNumber(out, 6) == 1;
        };
        auto material = [](std::int32_t m) { return [m](std::int32_t x) { return x == m; }; };
        if ((from != 0 && !simple(material(from))) || (to != 0 && !simple(material(to)))) return false;
        // a point joining or leaving the object: the union of all materials
        // (and so the background: its pockets, the exterior) keeps its topology too
        if ((from == 0 || to == 0) && !simple([](std::int32_t x) { return x != 0; })) return false;
        const std::size_t p = g.index(i, j, k);
        mat[p] = to;
        bool manifold = true;
        for (int c = 0; c < 8 && manifold; ++c) {
            const int bi = i - (c & 1), bj = j - (c >> 1 & 1), bk = k - (c >> 2 & 1);
            manifold = blockManifold(block(labels, bi, bj, bk).mat);
        }
        mat[p] = from;
        return manifold;
    };
    for (const auto& x : positions) {
        bool onGrid = true;
        for (int a = 0; a < 3; ++a) onGrid = onGrid && std::isfinite(x[a]) && x[a] > -1 && x[a] < g.dims[a];
        if (!onGrid) continue;
        const int ci = static_cast<int>(std::lround(x[0])), cj = static_cast<int>(std::lround(x[1])),
                  ck = static_cast<int>(std::lround(x[2]));
        // the most exposed point, then the material most of its neighbours
        // hold, then the nearest, then the first
        using Key = std::tuple<int, int, double, std::size_t, std::int32_t>;
        std::optional<Key> best;
        std::int32_t bestFrom = 0;
        bool nearEdit = false;
        for (int dk = -1; dk <= 1; ++dk)
            for (int dj = -1; dj <= 1; ++dj)
                for (int di = -1; di <= 1; ++di) {
                    const int i = ci + di, j = cj + dj, k = ck + dk;
                    // points on the outer layer stay background; their blocks reach past it
                    if (i < 1 || j < 1 || k < 1 || i + 1 >= nx || j + 1 >= ny || k + 1 >= nz) continue;
                    const std::size_t p = g.index(i, j, k);
                    if (std::any_of(edits.begin(), edits.end(), [&](const PointEdit& e) { return e.point == p; })) nearEdit = true;
                    if (isFrozen(p)) continue;
                    const std::int32_t from = mat[p];
                    std::array<std::int32_t, 6> nb;
                    int same = 0;
                    for (int d = 0; d < 6; ++d) {
                        nb[d] = mat[g.index(i + faceStep[d][0], j + faceStep[d][1], k + faceStep[d][2])];
                        same += nb[d] == from;
                    }
                    if (same > maxSame) continue;
                    const double dist = (x[0] - i) * (x[0] - i) + (x[1] - j) * (x[1] - j) + (x[2] - k) * (x[2] - k);
                    for (int d = 0; d < 6; ++d) {
                        const std::int32_t to = nb[d];
                        if (to == from || std::find(nb.begin(), nb.begin() + d, to) != nb.begin() + d) continue;
                        const Key key{same, -static_cast<int>(std::count(nb.begin(), nb.end(), to)), dist, p, to};
                        if ((best && !(key < *best)) || !allowed(i, j, k, from, to)) continue;
                        best = key;
                        bestFrom = from;
                    }
                }
        // one edit per place: a second inverted hex of an edited place waits
        // for the next attempt, which sees the mesh this edit gives
        if (!best || nearEdit) continue;
        const std::size_t p = std::get<3>(*best);
        mat[p] = std::get<4>(*best);
        edits.push_back({p, bestFrom, mat[p]});
    }
    return edits;
}

}  // namespace isohex::octree

// User sizing of the 27-tree: size limits as requests (a box with a sizing
// field, per-label sizes, --max-size's level), the grading's dilation, and
// requestsAround (the hook that refines around poor hexes).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "isohex/core/Quality.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/octree/AdaptiveHexes.hpp"
#include "isohex/octree/RefinementTree.hpp"
#include "isohex/octree/RequestMasks.hpp"
#include "isohex/octree/SizeLimits.hpp"

using namespace isohex;
using namespace isohex::octree;

namespace {

constexpr float kNoLimit = std::numeric_limits<float>::infinity();

Labels solid(std::array<int, 3> dims) {
    Grid g;
    g.dims = dims;
    return Labels{g, std::vector<std::int32_t>(g.size(), 1)};
}

int power3(int l) {
    int s = 1;
    while (l-- > 0) s *= 3;
    return s;
}

// Whether the level-l cell (i, j, k) is a leaf: unrefined, and its parent
// refined (or it is a root).
bool isLeaf(const RefinementTree& t, int l, int i, int j, int k) {
    const RefinementLevel& L = t.levels[static_cast<std::size_t>(l)];
    if (L.refined[L.index(i, j, k)]) return false;
    if (l == t.top()) return true;
    const RefinementLevel& P = t.levels[static_cast<std::size_t>(l) + 1];
    return P.refined[P.index(i / 3, j / 3, k / 3)] != 0;
}

// The smallest limit over the level-1 cells of level-l cell (i, j, k).
float limitOver(const CellSizeLimits& s, int l, int i, int j, int k) {
    const int n = power3(l - 1);
    float m = kNoLimit;
    for (int c = k * n; c < std::min((k + 1) * n, s.dims[2]); ++c)
        for (int b = j * n; b < std::min((j + 1) * n, s.dims[1]); ++b)
            for (int a = i * n; a < std::min((i + 1) * n, s.dims[0]); ++a) m = std::min(m, s.limit[s.index(a, b, c)]);
    return m;
}

// Leaves per level whose width exceeds their limit (must be none), and leaves per level.
void countLeaves(const RefinementTree& t, const CellSizeLimits& s, double finest, std::vector<int>& tooWide,
                 std::vector<int>& leaves) {
    tooWide.assign(static_cast<std::size_t>(t.top()) + 1, 0);
    leaves.assign(static_cast<std::size_t>(t.top()) + 1, 0);
    for (int l = 1; l <= t.top(); ++l) {
        const RefinementLevel& L = t.levels[static_cast<std::size_t>(l)];
        for (int k = 0; k < L.dims[2]; ++k)
            for (int j = 0; j < L.dims[1]; ++j)
                for (int i = 0; i < L.dims[0]; ++i) {
                    if (!isLeaf(t, l, i, j, k)) continue;
                    ++leaves[static_cast<std::size_t>(l)];
                    if (power3(l) * finest > limitOver(s, l, i, j, k) * (1 + 1e-6)) ++tooWide[static_cast<std::size_t>(l)];
                }
    }
}

void expectValidPositive(const AdaptiveMesh& a) {
    EXPECT_TRUE(validate(a.mesh).ok());
    for (Index h = 0; h < static_cast<Index>(a.mesh.hexCount()); ++h)
        ASSERT_GT(minJacobianDeterminant(hexCoords(a.mesh, h)), 0) << "hex " << h;
}

}  // namespace

TEST(SizeLimits, ABoxWithASizingFieldGetsNoLeafWiderThanItsLimit) {
    // 81^3 points of 0.5 mm: level-l cells are 1.5, 4.5, 13.5 mm wide. The
    // level-1 cells with x < 9 (points x < 27) allow 1.5 mm, those with
    // 9 <= x < 18 allow 5 mm, the rest nothing.
    const std::array<int, 3> points{81, 81, 81};
    const double finest = 0.5;
    CellSizeLimits s = noSizeLimits(points);
    ASSERT_EQ(s.dims, (std::array<int, 3>{27, 27, 27}));
    for (int k = 0; k < 27; ++k)
        for (int j = 0; j < 27; ++j)
            for (int i = 0; i < 18; ++i) s.limit[s.index(i, j, k)] = i < 9 ? 1.5f : 5.0f;
    const RequestMasks r = requestsForLimits(s, points, finest, 3);
    ASSERT_EQ(r.size(), 4u);
    EXPECT_EQ(countRequests({{}, r[1]}), 0u);                    // 1.5 mm cells are allowed everywhere
    EXPECT_EQ(countRequests({{}, {}, r[2]}), 3u * 9 * 9);        // 4.5 mm cells over the 1.5 mm limit
    EXPECT_EQ(countRequests({{}, {}, {}, r[3]}), 2u * 3 * 3);    // 13.5 mm cells over either limit
    const RefinementTree t = closeRefinement(points, 3, r);
    std::vector<int> tooWide, leaves;
    countLeaves(t, s, finest, tooWide, leaves);
    for (int l = 1; l <= 3; ++l) EXPECT_EQ(tooWide[static_cast<std::size_t>(l)], 0) << "level " << l;
    EXPECT_GT(leaves[2], 0);  // where the limit is 5 mm, 4.5 mm leaves
    const Labels labels = solid(points);
    expectValidPositive(assembleAdaptive(leafHexes(t, labels), labels.grid));
}

TEST(SizeLimits, PerLabelSizesLimitTheCellsHoldingTheLabel) {
    // Label 1 where x < 9, label 2 elsewhere; label 1 at the finest size,
    // label 2 no wider than 9 steps.
    const std::array<int, 3> points{27, 27, 27};
    Labels l = solid(points);
    for (int k = 0; k < 27; ++k)
        for (int j = 0; j < 27; ++j)
            for (int i = 0; i < 27; ++i) l.material[l.grid.index(i, j, k)] = i < 9 ? 1 : 2;
    const CellSizeLimits s = labelSizeLimits(l, {{1, 1.0}, {2, 9.0}});
    EXPECT_EQ(s.limit[s.index(2, 4, 4)], 1.0f);
    EXPECT_EQ(s.limit[s.index(3, 4, 4)], 9.0f);
    EXPECT_EQ(labelSizeLimits(l, {{7, 1.0}}).limit[s.index(0, 0, 0)], kNoLimit);  // a label absent: no limit
    const RequestMasks r = requestsForLimits(s, points, 1.0, 3);
    const auto d1 = levelDims(points, 1);
    for (int k = 0; k < d1[2]; ++k)
        for (int j = 0; j < d1[1]; ++j)
            for (int i = 0; i < d1[0]; ++i)
                EXPECT_EQ(r[1][s.index(i, j, k)], i < 3 ? 1 : 0) << i << " " << j << " " << k;
    EXPECT_EQ(countRequests({{}, {}, r[2]}), 9u);  // the level-2 cells holding label 1 (limit 1 < 9)
    EXPECT_EQ(countRequests({{}, {}, {}, r[3]}), 1u);  // the root is 27 wide, above 9
}

TEST(SizeLimits, MaxSizeChoosesTheCoarsestLevelNoWiderThanIt) {
    EXPECT_EQ(levelForMaxSize(7.5, 1.0, 3), 1);
    EXPECT_EQ(levelForMaxSize(9.0, 1.0, 3), 2);
    EXPECT_EQ(levelForMaxSize(2.0, 1.0, 3), 0);
    EXPECT_EQ(levelForMaxSize(1000, 1.0, 3), 3);
    EXPECT_EQ(levelForMaxSize(1.5, 0.5, 3), 1);
}

TEST(RequestMasks, OrKeepsEveryRequestAndDilationFillsACube) {
    const std::array<int, 3> points{27, 27, 27};
    RequestMasks a = emptyRequests(points, 2), b = emptyRequests(points, 2);
    a[1][0] = 1;
    b[1][5] = 1;
    b[2][1] = 1;
    orRequests(a, b);
    EXPECT_EQ(countRequests(a), 3u);
    RequestMasks empty;
    orRequests(empty, a);
    EXPECT_EQ(countRequests(empty), 3u);

    std::vector<std::uint8_t> m(7 * 7 * 7, 0);
    m[(3 * 7 + 3) * 7 + 3] = 1;
    dilateCells(m, {7, 7, 7}, 2);
    EXPECT_EQ(std::count(m.begin(), m.end(), 1), 125);
    EXPECT_EQ(m[(1 * 7 + 5) * 7 + 1], 1);
    EXPECT_EQ(m[(0 * 7 + 3) * 7 + 3], 0);
}

TEST(Grading, KeepsGCellsOfALevelAroundItsTransitionCells) {
    // One refined level-1 cell at the centre of 243^3 points: with grading 0
    // the closure refines the level-2 parents of it and its template ring; with
    // grading 2 every level-1 cell within two cells of those has its parent
    // refined, and the same at level 2.
    const std::array<int, 3> points{243, 243, 243};
    RequestMasks r = emptyRequests(points, 3);
    const auto d1 = levelDims(points, 1);
    r[1][(static_cast<std::size_t>(40) * d1[1] + 40) * d1[0] + 40] = 1;
    const RefinementTree plain = closeRefinement(points, 3, r);
    const RefinementTree graded = closeRefinement(points, 3, r, 2);
    EXPECT_EQ(plain.graded[2] + plain.graded[3], 0u);
    EXPECT_GT(graded.graded[2], 0u);
    auto refinedAt = [](const RefinementTree& t, int l) {
        const auto& v = t.levels[static_cast<std::size_t>(l)].refined;
        return std::count(v.begin(), v.end(), 1);
    };
    EXPECT_GT(refinedAt(graded, 2), refinedAt(plain, 2));
    for (int l = 1; l <= 2; ++l) {
        const RefinementLevel& L = graded.levels[static_cast<std::size_t>(l)];
        const RefinementLevel& P = graded.levels[static_cast<std::size_t>(l) + 1];
        for (int k = 0; k < L.dims[2]; ++k)
            for (int j = 0; j < L.dims[1]; ++j)
                for (int i = 0; i < L.dims[0]; ++i) {
                    const std::size_t c = L.index(i, j, k);
                    if (!L.refined[c] && !L.marks[c]) continue;
                    for (int dk = -2; dk <= 2; ++dk)
                        for (int dj = -2; dj <= 2; ++dj)
                            for (int di = -2; di <= 2; ++di)
                                if (L.contains(i + di, j + dj, k + dk)) {
                                    ASSERT_TRUE(P.refined[P.index((i + di) / 3, (j + dj) / 3, (k + dk) / 3)])
                                        << "level " << l << " cell " << i + di << " " << j + dj << " " << k + dk;
                                }
                }
    }
    const Labels labels = solid(points);
    const AdaptiveMesh a = assembleAdaptive(leafHexes(graded, labels), labels.grid);
    expectValidPositive(a);
    EXPECT_LT(a.mesh.hexCount(), labels.grid.size() / 10);
}

TEST(RequestMasks, RequestsAroundFindsTheCellOfAWorldPosition) {
    Grid g;
    g.origin = {10, 0, 0};
    g.axes = {{{0, 2, 0}, {2, 0, 0}, {0, 0, 2}}};  // axis 0 along world y, axis 1 along world x
    g.dims = {27, 18, 9};
    const auto d = levelDims(g.dims, 1);
    ASSERT_EQ(d, (std::array<int, 3>{9, 6, 3}));
    // grid point (7, 4, 2) sits at world (10 + 8, 14, 4); a little off it still finds it
    const std::vector<std::uint8_t> one = requestsAround({{18.4, 14.3, 3.8}, {-100, 0, 0}}, g, 0);
    ASSERT_EQ(one.size(), 9u * 6 * 3);
    EXPECT_EQ(std::count(one.begin(), one.end(), 1), 1);
    EXPECT_EQ(one[(0 * 6 + 1) * 9 + 2], 1);  // cell (7/3, 4/3, 2/3)
    const std::vector<std::uint8_t> ring = requestsAround({{18.4, 14.3, 3.8}}, g, 1);
    EXPECT_EQ(std::count(ring.begin(), ring.end(), 1), 3 * 3 * 2);  // clipped at k = 0 below
}

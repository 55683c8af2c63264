// The field the repaired labels are the signs of (RepairedDomain), and where
// dual contouring puts the vertices of cells the repair changed or where two
// materials meet the outside.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "AnalyticDomains.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/octree/DualContour.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/RepairedDomain.hpp"

using namespace isohex;
using namespace isohex::octree;
using namespace isohex::test;

namespace {

// A sphere on a unit grid with one point just outside it added to the solid
// and one just inside removed, as the repair would flip them.
struct Flipped {
    AnalyticDomain domain{{sphere({9.2, 9.1, 8.8}, 5.3)}};
    Labels sampled, repaired;
    std::array<int, 3> added{}, removed{};
    Flipped() {
        sampled = sampleLabels(domain, unitGrid(19));
        repaired = sampled;
        // along +x from the centre: the last point inside and the first outside
        int i = 9;
        while (sampled.material[sampled.grid.index(i + 1, 9, 9)] == 1) ++i;
        removed = {i, 9, 9};
        int j = 9;  // along -y from the centre: the first point outside
        while (sampled.material[sampled.grid.index(9, j, 9)] == 1) --j;
        added = {9, j, 9};
        repaired.material[repaired.grid.index(removed[0], removed[1], removed[2])] = 0;
        repaired.material[repaired.grid.index(added[0], added[1], added[2])] = 1;
    }
};

// The zero set of field is within r of x: the field changes sign within r
// along one of the 26 grid directions or the gradient.
bool zeroSetWithin(const Domain& d, std::int32_t m, const Vec3& x, double r) {
    const double f0 = d.value(m, x);
    if (f0 == 0) return true;
    Vec3 gr;
    d.value(m, x, &gr);
    std::vector<Vec3> dirs{gr, {-gr[0], -gr[1], -gr[2]}};
    for (int a = -1; a <= 1; ++a)
        for (int b = -1; b <= 1; ++b)
            for (int c = -1; c <= 1; ++c)
                if (a || b || c) dirs.push_back({double(a), double(b), double(c)});
    for (const Vec3& v : dirs) {
        const double len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        if (!(len > 0)) continue;
        for (int s = 1; s <= 32; ++s) {
            const double t = r * s / 32.0 / len;
            if ((d.value(m, {x[0] + t * v[0], x[1] + t * v[1], x[2] + t * v[2]}) < 0) != (f0 < 0)) return true;
        }
    }
    return false;
}

}  // namespace

TEST(RepairedDomain, EveryGridPointHasTheSignOfItsRepairedLabel) {
    const Flipped f;
    const RepairedDomain r(f.domain, f.sampled, f.repaired);
    EXPECT_EQ(r.changedPoints(), 2u);
    const Grid& g = f.repaired.grid;
    for (int k = 0; k < g.dims[2]; ++k)
        for (int j = 0; j < g.dims[1]; ++j)
            for (int i = 0; i < g.dims[0]; ++i)
                EXPECT_EQ(r.value(1, g.point(i, j, k)) < 0, f.repaired.material[g.index(i, j, k)] == 1)
                    << i << " " << j << " " << k;
}

TEST(RepairedDomain, FieldIsTheScansFartherThanOneGridStepFromAChange) {
    const Flipped f;
    const RepairedDomain r(f.domain, f.sampled, f.repaired);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(0.0, 18.0);
    std::size_t near = 0;
    for (int n = 0; n < 20000; ++n) {
        const Vec3 x{u(rng), u(rng), u(rng)};
        bool close = false;
        for (const auto& p : {f.added, f.removed}) {
            bool within = true;
            for (int a = 0; a < 3; ++a) within = within && std::abs(x[a] - p[a]) < 1.0;
            close = close || within;
        }
        near += close;
        if (!close) {
            EXPECT_EQ(r.value(1, x), f.domain.value(1, x, nullptr)) << x[0] << " " << x[1] << " " << x[2];
            EXPECT_EQ(r.nearChange(x), false);
        }
    }
    EXPECT_GT(near, 0u);
    // continuous across the hat's edge
    const Vec3 edge{double(f.added[0]) + 1.0, double(f.added[1]) + 0.3, double(f.added[2]) - 0.6};
    EXPECT_NEAR(r.value(1, edge), f.domain.value(1, edge, nullptr), 1e-12);
}

TEST(RepairedDomain, GradientIsTheFieldsDerivative) {
    const Flipped f;
    const RepairedDomain r(f.domain, f.sampled, f.repaired);
    for (const Vec3& x : {Vec3{f.added[0] + 0.31, f.added[1] - 0.42, f.added[2] + 0.17},
                          Vec3{f.removed[0] - 0.27, f.removed[1] + 0.61, f.removed[2] - 0.35}}) {
        Vec3 g;
        r.value(1, x, &g);
        const double h = 1e-5;
        for (int a = 0; a < 3; ++a) {
            Vec3 p = x, q = x;
            p[a] += h;
            q[a] -= h;
            EXPECT_NEAR(g[a], (r.value(1, p) - r.value(1, q)) / (2 * h), 1e-4) << a;
        }
    }
}

TEST(RepairedDomain, VerticesOfCellsAroundAChangedPointLieOnItsZeroSet) {
    const Flipped f;
    const RepairedDomain r(f.domain, f.sampled, f.repaired);
    ExtractStats st;
    const HexMesh m = dualContourHexes(f.repaired, r, {}, &st);
    const Topology t = buildTopology(m);
    std::size_t checked = 0;
    for (Index v : t.boundaryNodes) {
        const Vec3& x = m.nodes[v];
        if (!r.nearChange(x)) continue;
        ++checked;
        EXPECT_TRUE(zeroSetWithin(r, 1, x, 0.1)) << "node " << v << " at " << x[0] << " " << x[1] << " " << x[2];
        // the scan's own surface does not cross every such cell
    }
    EXPECT_GE(checked, 8u);
}

TEST(DualContour, OuterVerticesWhereTwoMaterialsMeetTheOutsideLieOnTheirUnion) {
    // Two boxes with rounded edges sharing a face, inside one box with
    // rounded edges (as two labels' own isosurfaces each round the corner
    // where they meet the outside, while the labelled region's does not):
    // along the rim of the shared face, cells hold both materials and the
    // outside, and the vertex goes onto the union's surface, not into the
    // groove the two materials' surfaces leave there.
    const Sdf a = roundedBox({3.3, 3.4, 3.6}, {9.45, 12.6, 12.7}, 1.2);
    const Sdf b = roundedBox({9.45, 3.4, 3.6}, {15.7, 12.6, 12.7}, 1.2);
    const Sdf u = roundedBox({3.3, 3.4, 3.6}, {15.7, 12.6, 12.7}, 1.2);
    const AnalyticDomain d({a, b}, u);
    Labels l = sampleLabels(d, unitGrid(19));
    repairNonManifold(l, d);
    const HexMesh m = dualContourHexes(l, d);
    const Topology t = buildTopology(m);
    std::size_t junctions = 0;
    for (Index v : t.boundaryNodes) {
        const Vec3& x = m.nodes[v];
        // the cell of x holds both materials and the outside
        const int ci = static_cast<int>(std::floor(x[0])), cj = static_cast<int>(std::floor(x[1])),
                  ck = static_cast<int>(std::floor(x[2]));
        bool has[3] = {false, false, false}, agrees = true;
        for (int c = 0; c < 8; ++c) {
            const int i = ci + (c & 1), j = cj + (c >> 1 & 1), k = ck + (c >> 2 & 1);
            const std::int32_t mat = l.material[l.grid.index(i, j, k)];
            has[mat] = true;
            // a grid point outside both boxes but inside the union (in the
            // groove): the union's surface need not cross this cell
            agrees = agrees && (mat != 0) == (u(l.grid.point(i, j, k)) < 0);
        }
        if (!(has[0] && has[1] && has[2]) || !agrees) continue;
        ++junctions;
        EXPECT_LT(std::abs(u(x)), 0.1) << x[0] << " " << x[1] << " " << x[2];
    }
    EXPECT_GE(junctions, 20u);
}

// The 27-tree's transition templates: each tiles its cube with positively
// oriented hexes, and each face of every placement shows exactly the pattern
// its four corners ask for (the patterns are written here from their
// definition, independently of the templates' data).
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <iostream>
#include <map>
#include <set>
#include <vector>

#include <nlohmann/json.hpp>

#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/octree/TransitionTemplates.hpp"

using namespace isohex;
using namespace isohex::octree;

namespace {

using P2 = std::array<int, 2>;
using Quad2 = std::set<P2>;
using Pattern = std::set<Quad2>;

// 2-D patterns in twelfths of a child on a 3x3 face, corner (0,0) = bit 0, (36,0) bit 1, (0,36) bit 2, (36,36) bit 3.
Pattern quads(std::initializer_list<std::initializer_list<std::array<double, 2>>> qs) {
    Pattern p;
    for (const auto& q : qs) {
        Quad2 s;
        for (const auto& x : q) s.insert({static_cast<int>(x[0] * kChildSteps), static_cast<int>(x[1] * kChildSteps)});
        p.insert(s);
    }
    return p;
}
Pattern unitQuads(int rows) {
    Pattern p;
    for (int j = 0; j < rows; ++j)
        for (int i = 0; i < 3; ++i) {
            const int u = kChildSteps * i, v = kChildSteps * j, d = kChildSteps;
            p.insert(Quad2{P2{u, v}, P2{u + d, v}, P2{u + d, v + d}, P2{u, v + d}});
        }
    return p;
}
// The canonical patterns: vertex at corner (0,0), edge along v = 0.
const std::vector<std::pair<std::uint8_t, Pattern>>& canonicalPatterns() {
    static const std::vector<std::pair<std::uint8_t, Pattern>> all = [] {
        std::vector<std::pair<std::uint8_t, Pattern>> v;
        v.emplace_back(0x0, quads({{{0, 0}, {3, 0}, {3, 3}, {0, 3}}}));
        v.emplace_back(0x1, quads({{{0, 0}, {1, 0}, {1, 1}, {0, 1}},
                                   {{1, 0}, {2, 0}, {2, 2}, {1, 1}},
                                   {{0, 1}, {1, 1}, {2, 2}, {0, 2}},
                                   {{2, 0}, {3, 0}, {3, 3}, {2, 2}},
                                   {{0, 2}, {2, 2}, {3, 3}, {0, 3}}}));
        Pattern edge = unitQuads(2);
        for (const auto& q : quads({{{0, 2}, {1, 2}, {1, 2.5}, {0, 3}},
                                    {{1, 2}, {2, 2}, {2, 2.5}, {1, 2.5}},
                                    {{2, 2}, {3, 2}, {3, 3}, {2, 2.5}},
                                    {{1, 2.5}, {2, 2.5}, {3, 3}, {0, 3}}}))
            edge.insert(q);
        v.emplace_back(0x3, edge);
        v.emplace_back(0xF, unitQuads(3));
        return v;
    }();
    return all;
}

// The pattern a face with these marked corners must show: every edge with a
// marked end is split in three, so two diagonal or three corners show the
// nine unit quads too.
Pattern expectedPattern(std::uint8_t faceMask) {
    if (faceMask == 0x6 || faceMask == 0x9 || std::popcount(static_cast<unsigned>(faceMask)) >= 3) return unitQuads(3);
    for (int s = 0; s < 8; ++s) {  // the square's 8 symmetries: swap, flip u, flip v
        const bool swap = s & 1, fu = s & 2, fv = s & 4;
        const auto map = [&](P2 p) {
            if (swap) std::swap(p[0], p[1]);
            if (fu) p[0] = kCellSteps - p[0];
            if (fv) p[1] = kCellSteps - p[1];
            return p;
        };
        for (const auto& [mask, pattern] : canonicalPatterns()) {
            std::uint8_t m = 0;
            for (int c = 0; c < 4; ++c)
                if (mask >> c & 1) {
                    const P2 q = map({kCellSteps * (c & 1), kCellSteps * (c >> 1)});
                    m = static_cast<std::uint8_t>(m | 1u << (q[0] / kCellSteps + 2 * (q[1] / kCellSteps)));
                }
            if (m != faceMask) continue;
            Pattern out;
            for (const auto& quad : pattern) {
                Quad2 t;
                for (const P2& x : quad) t.insert(map(x));
                out.insert(t);
            }
            return out;
        }
    }
    return {};  // no pattern: such a face must never appear
}

// The hexes of a placement as a mesh (nodes merged by lattice position, child units).
HexMesh templateMesh(const std::vector<TemplateHex>& hexes) {
    HexMesh m;
    std::map<TemplatePoint, Index> id;
    for (const auto& h : hexes) {
        Hex hex;
        for (int c = 0; c < 8; ++c) {
            auto [it, added] = id.emplace(h[c], static_cast<Index>(m.nodes.size()));
            if (added) m.addNode({h[c][0] / double(kChildSteps), h[c][1] / double(kChildSteps), h[c][2] / double(kChildSteps)});
            hex[c] = it->second;
        }
        m.addHex(hex);
    }
    return m;
}

std::vector<TemplateHex> placed(TemplateKind kind, const CubeSymmetry& s) {
    std::vector<TemplateHex> out;
    for (const auto& h : templateHexes(kind)) out.push_back(s.apply(h));
    return out;
}

// Checks that the hexes tile [0,3]^3 conformally with positive Jacobians and
// that each cube face shows the pattern of its corners in `mask`. Returns the
// smallest scaled Jacobian.
double checkPlacement(const std::vector<TemplateHex>& hexes, std::uint8_t mask) {
    const HexMesh m = templateMesh(hexes);
    const ValidityReport v = validate(m);
    EXPECT_TRUE(v.ok()) << toJson(v).dump();
    double volume = 0, worst = 1;
    for (Index h = 0; h < static_cast<Index>(m.hexCount()); ++h) {
        const HexCoords x = hexCoords(m, h);
        EXPECT_GT(minCornerDeterminant(x), 0);
        EXPECT_GT(centreDeterminant(x), 0);
        volume += hexVolume(x);
        worst = std::min(worst, scaledJacobian(x));
    }
    EXPECT_NEAR(volume, 27.0, 1e-9);
    // Boundary quads: all on the cube's faces, grouped by face.
    const Topology t = buildTopology(m);
    std::map<int, Pattern> faces;  // face = 2 * axis + side
    for (Index q : t.boundaryQuads) {
        const auto& qn = t.quads[static_cast<std::size_t>(q)].nodes;
        int face = -1;
        for (int a = 0; a < 3 && face < 0; ++a)
            for (int side = 0; side < 2 && face < 0; ++side) {
                bool all = true;
                for (Index n : qn) all = all && m.nodes[static_cast<std::size_t>(n)][a] == 3.0 * side;
                if (all) face = 2 * a + side;
            }
        if (face < 0) {
            ADD_FAILURE() << "a boundary quad inside the cube: the hexes leave a gap";
            continue;
        }
        Quad2 s;
        const int a = face / 2, u = a == 0 ? 1 : 0, w = a == 2 ? 1 : 2;
        for (Index n : qn) {
            const Vec3& x = m.nodes[static_cast<std::size_t>(n)];
            s.insert({static_cast<int>(std::lround(x[u] * kChildSteps)), static_cast<int>(std::lround(x[w] * kChildSteps))});
        }
        faces[face].insert(s);
    }
    for (int face = 0; face < 6; ++face) {
        const int a = face / 2, side = face % 2, u = a == 0 ? 1 : 0, w = a == 2 ? 1 : 2;
        std::uint8_t fm = 0;
        for (int c = 0; c < 8; ++c) {
            const int xyz[3] = {c & 1, c >> 1 & 1, c >> 2 & 1};
            if (xyz[a] != side || !(mask >> c & 1)) continue;
            fm = static_cast<std::uint8_t>(fm | 1u << (xyz[u] + 2 * xyz[w]));
        }
        EXPECT_EQ(faces[face], expectedPattern(fm)) << "face " << face << " of mask " << int(mask);
    }
    return worst;
}

}  // namespace

TEST(TransitionTemplates, FortyEightSymmetriesHalfOfThemMirrors) {
    const auto syms = cubeSymmetries();
    ASSERT_EQ(syms.size(), 48u);
    int mirrors = 0;
    std::set<std::vector<int>> images;
    for (const auto& s : syms) {
        mirrors += s.reversesOrientation();
        std::vector<int> img;
        for (int c = 0; c < 8; ++c) img.push_back(s.applyToMask(static_cast<std::uint8_t>(1u << c)));
        images.insert(img);
    }
    EXPECT_EQ(mirrors, 24);
    EXPECT_EQ(images.size(), 48u);  // all distinct on the corners
}

TEST(TransitionTemplates, EachTemplateTilesItsCubeAndShowsItsFacePatterns) {
    const std::pair<TemplateKind, const char*> kinds[] = {
        {TemplateKind::Vertex, "vertex"}, {TemplateKind::Edge, "edge"},      {TemplateKind::Face, "face"},
        {TemplateKind::TwoFace, "two-face"}, {TemplateKind::Full, "full"}};
    const std::map<TemplateKind, double> floor = {
        {TemplateKind::Vertex, 0.577}, {TemplateKind::Edge, 0.408}, {TemplateKind::Face, 0.30},
        {TemplateKind::TwoFace, 0.258},  {TemplateKind::Full, 1.0}};
    const std::map<TemplateKind, std::size_t> count = {
        {TemplateKind::Vertex, 7}, {TemplateKind::Edge, 17}, {TemplateKind::Face, 31}, {TemplateKind::TwoFace, 45}, {TemplateKind::Full, 27}};
    for (const auto& [kind, name] : kinds) {
        EXPECT_EQ(templateHexes(kind).size(), count.at(kind)) << name;
        double worst = 1;
        for (const auto& s : cubeSymmetries())
            worst = std::min(worst, checkPlacement(placed(kind, s), s.applyToMask(canonicalMask(kind))));
        std::cout << "[ template ] " << name << ": " << templateHexes(kind).size()
                  << " hexes, min scaled Jacobian " << worst << "\n";
        EXPECT_GE(worst, floor.at(kind) - 1e-3) << name;
    }
}

TEST(TransitionTemplates, EveryMaskIsPlainATemplateOrPromotedToTheFewestMoreCorners) {
    int plain = 0, templ = 0, full = 0, promote = 0;
    for (int m = 0; m < 256; ++m) {
        const auto mask = static_cast<std::uint8_t>(m);
        const TemplateChoice c = chooseTemplate(mask);
        const int n = std::popcount(static_cast<unsigned>(m));
        switch (c.action) {
        case TemplateChoice::Action::Plain: ++plain; EXPECT_EQ(m, 0); break;
        case TemplateChoice::Action::Promote: {
            ++promote;
            EXPECT_EQ(c.promoteTo & mask, mask);
            const TemplateChoice to = chooseTemplate(c.promoteTo);
            EXPECT_EQ(to.action, TemplateChoice::Action::Template);
            // no template in between: every mask with fewer corners is promoted too
            for (int s = 0; s < 256; ++s)
                if ((s & m) == m && std::popcount(static_cast<unsigned>(s)) < std::popcount(c.promoteTo))
                    EXPECT_NE(chooseTemplate(static_cast<std::uint8_t>(s)).action, TemplateChoice::Action::Template) << m << " " << s;
            break;
        }
        case TemplateChoice::Action::Template:
            ++templ;
            full += c.kind == TemplateKind::Full;
            if (c.kind != TemplateKind::Full) EXPECT_EQ(c.symmetry.applyToMask(canonicalMask(c.kind)), mask);
            else EXPECT_GE(n, 4);
            checkPlacement(placed(c.kind, c.symmetry), mask);
            break;
        }
        if (n == 1) EXPECT_EQ(c.kind, TemplateKind::Vertex);
        if (n == 7 || n == 8) EXPECT_EQ(c.kind, TemplateKind::Full);
        if (n == 6) EXPECT_EQ(c.action, TemplateChoice::Action::Template) << m;  // two-face or FULL
    }
    EXPECT_EQ(plain, 1);
    EXPECT_EQ(templ - full, 8 + 12 + 6 + 12);  // corners, edges, faces, pairs of adjacent faces
    std::cout << "[ masks ] " << full << " take the 27 unit cubes, " << promote << " are promoted\n";
    EXPECT_EQ(plain + templ + promote, 256);
}

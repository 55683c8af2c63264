// validate(): the seed's primal constraints (section 2.4.1) checked on small
// meshes that each carry one defect. Every test says which keys must fire; when
// a defect necessarily brings another one with it, the test says why.
#include <gtest/gtest.h>

#include <array>
#include <map>
#include <set>
#include <string>

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/Validate.hpp"
#include "support/Blocks.hpp"

using namespace isohex;
using isohex::test::makeBlock;

namespace {

// Node id of grid point (i, j, k) in makeBlock(nx, ny, ...).
Index blockNode(int nx, int ny, int i, int j, int k) { return static_cast<Index>((k * (ny + 1) + j) * (nx + 1) + i); }

// Appends `b` to `a`, sharing the nodes that sit at exactly the same position:
// how two solids that touch are glued together in these tests.
HexMesh weld(HexMesh a, const HexMesh& b) {
    std::map<Vec3, Index> at;
    for (std::size_t i = 0; i < a.nodes.size(); ++i) at.emplace(a.nodes[i], static_cast<Index>(i));
    std::vector<Index> to(b.nodes.size());
    for (std::size_t j = 0; j < b.nodes.size(); ++j) {
        const auto it = at.find(b.nodes[j]);
        to[j] = it != at.end() ? it->second : a.addNode(b.nodes[j]);
    }
    for (std::size_t h = 0; h < b.hexes.size(); ++h) {
        Hex x = b.hexes[h];
        for (Index& v : x) v = to[v];
        a.addHex(x, b.material[h]);
    }
    return a;
}

HexMesh unitCube(Vec3 origin = {0, 0, 0}) { return makeBlock(1, 1, 1, 1.0, origin); }

std::set<std::string> keys(const ValidityReport& r) {
    std::set<std::string> k;
    for (const auto& [key, d] : r.defects) k.insert(key);
    return k;
}

const DefectKind& defect(const ValidityReport& r, const std::string& key) {
    static const DefectKind none;
    const auto it = r.defects.find(key);
    return it == r.defects.end() ? none : it->second;
}

using Ids = std::vector<Index>;

// The top face (local nodes 4-7, in VTK order) of hex h.
std::array<Index, 4> topFace(const HexMesh& m, Index h) {
    const Hex& x = m.hexes[h];
    return {x[4], x[5], x[6], x[7]};
}

// A hex with the given bottom and top faces.
Hex hexOf(const std::array<Index, 4>& bottom, const std::array<Index, 4>& top) {
    return {bottom[0], bottom[1], bottom[2], bottom[3], top[0], top[1], top[2], top[3]};
}

// Four new nodes at height z in VTK order over the unit square.
std::array<Index, 4> addSquare(HexMesh& m, double z) {
    std::array<Index, 4> ids;
    const Vec3 corners[4] = {{0, 0, z}, {1, 0, z}, {1, 1, z}, {0, 1, z}};
    for (int i = 0; i < 4; ++i) ids[i] = m.addNode(corners[i]);
    return ids;
}

}  // namespace

// ------------------------------------------------------------ valid meshes

TEST(Validate, CleanBlockIsValid) {
    const ValidityReport r = validate(makeBlock(3, 2, 2));
    EXPECT_TRUE(r.ok());
    EXPECT_TRUE(r.defects.empty());
}

TEST(Validate, InterfaceBetweenTwoMaterialsIsValid) {
    // Each material's exterior surface and the interface are open surfaces that
    // end on the curve where they meet: one quad of each per edge there.
    HexMesh m = makeBlock(2, 1, 1);
    m.material[1] = 2;
    const ValidityReport r = validate(m);
    EXPECT_TRUE(r.ok()) << toJson(r).dump();
}

TEST(Validate, JunctionOfThreeMaterialsIsValid) {
    // Hexes (0,0) and (1,0) of material 1, (0,1) of 2, (1,1) of 3.
    HexMesh m = makeBlock(2, 2, 1);
    m.material = {1, 1, 2, 3};
    const ValidityReport r = validate(m);
    EXPECT_TRUE(r.ok()) << toJson(r).dump();
}

TEST(Validate, EmptyMeshIsValid) { EXPECT_TRUE(validate(HexMesh{}).ok()); }

// ------------------------------------------------------------ one defect each

TEST(Validate, HexWithRepeatedNodeIsReported) {
    // A unit cube whose corner 6 is collapsed onto corner 7 (a wedge written as a hex).
    HexMesh m;
    for (Vec3 p : {Vec3{0, 0, 0}, Vec3{1, 0, 0}, Vec3{1, 1, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}, Vec3{1, 0, 1},
                   Vec3{0, 1, 1}})
        m.addNode(p);
    m.addHex({0, 1, 2, 3, 4, 5, 6, 6});
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), std::set<std::string>{"repeated_node"}) << toJson(r).dump();
    EXPECT_EQ(defect(r, "repeated_node").count, 1u);
    EXPECT_EQ(defect(r, "repeated_node").examples, Ids{0});
    EXPECT_EQ(defect(r, "repeated_node").entity, "hex");
}

TEST(Validate, QuadSharedByThreeHexesIsReported) {
    // A unit cube with two hexes stacked on its top face: one up to z = 2 and
    // one, overlapping it, up to z = 1.5. The third hex's sides put three
    // surface quads on each edge of the shared face, so those four edges and
    // their four nodes are non-manifold as well.
    HexMesh m = unitCube();
    const auto shared = topFace(m, 0);
    m.addHex(hexOf(shared, addSquare(m, 2.0)));
    m.addHex(hexOf(shared, addSquare(m, 1.5)));
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), (std::set<std::string>{"overfull_quad", "nonmanifold_edge", "nonmanifold_node"}))
        << toJson(r).dump();
    EXPECT_EQ(r.count("overfull_quad"), 1u);
    EXPECT_EQ(r.count("nonmanifold_edge"), 4u);
    EXPECT_EQ(r.count("nonmanifold_node"), 4u);
    ASSERT_EQ(defect(r, "overfull_quad").where.size(), 1u);
    EXPECT_EQ(defect(r, "overfull_quad").where[0], (Vec3{0.5, 0.5, 1.0}));
}

TEST(Validate, DuplicateHexIsReportedOnceForTheLaterCopy) {
    HexMesh m = unitCube();
    m.addHex(m.hexes[0]);
    const ValidityReport r = validate(m);
    // The copies share all six quads, which is not reported again as a doublet
    // or as misorientation.
    EXPECT_EQ(keys(r), std::set<std::string>{"duplicate_hex"}) << toJson(r).dump();
    EXPECT_EQ(r.count("duplicate_hex"), 1u);
    EXPECT_EQ(defect(r, "duplicate_hex").examples, Ids{1});
}

TEST(Validate, HexDoubletIsReported) {
    // The classic doublet: square a b c d split through an inner node p into
    // quads (a b c p) and (a p c d), which share edges a-p and p-c; extruded one
    // layer, the two hexes share two faces. The angles at p sum to 360 degrees,
    // so one hex must be reflex there (here the second: p sits on the first
    // one's side of the diagonal a-c), and the bottom and top faces of the two
    // hexes are quad doublets.
    HexMesh m;
    for (double z : {0.0, 1.0})
        for (Vec3 p : {Vec3{0, 0, z}, Vec3{2, 0, z}, Vec3{2, 2, z}, Vec3{0, 2, z}, Vec3{0.8, 1.2, z}}) m.addNode(p);
    const Index a = 0, b = 1, c = 2, d = 3, p = 4, up = 5;
    m.addHex({a, b, c, p, a + up, b + up, c + up, p + up});
    m.addHex({a, p, c, d, a + up, p + up, c + up, d + up});
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), (std::set<std::string>{"hex_doublet", "quad_doublet", "inverted_hex"})) << toJson(r).dump();
    EXPECT_EQ(defect(r, "hex_doublet").examples, (Ids{0, 1}));
    EXPECT_EQ(r.count("quad_doublet"), 4u);
    EXPECT_EQ(defect(r, "inverted_hex").examples, Ids{1});
}

TEST(Validate, QuadDoubletOnTheBoundaryIsReported) {
    // A 2x2x2 block with a crack along the face between hexes 0 and 1: hex 1
    // gets its own copy of the block-edge corner (1,0,0). The two faces of the
    // crack then share the edges from the centre node to (1,1,0) and (1,0,1):
    // a surface node (the centre) with only two quads around it.
    HexMesh m = makeBlock(2, 2, 2);
    const Index corner = blockNode(2, 2, 1, 0, 0);
    const Index copy = m.addNode(m.nodes[corner]);
    ASSERT_EQ(m.hexes[1][0], corner);
    m.hexes[1][0] = copy;
    const ValidityReport r = validate(m);
    // the copy sits where the corner is: the crack is an unmerged node too
    EXPECT_EQ(keys(r), (std::set<std::string>{"quad_doublet", "coincident_node"})) << toJson(r).dump();
    EXPECT_EQ(r.count("quad_doublet"), 2u);
    EXPECT_EQ(r.count("coincident_node"), 2u);
    EXPECT_EQ(defect(r, "quad_doublet").entity, "quad");
}

TEST(Validate, EdgeWhereTwoCubesTouchIsNonManifold) {
    // Four surface quads on the shared edge; its two end nodes are pinched too.
    const HexMesh m = weld(unitCube(), unitCube({1, 1, 0}));
    ASSERT_EQ(m.nodes.size(), 14u);
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), (std::set<std::string>{"nonmanifold_edge", "nonmanifold_node"})) << toJson(r).dump();
    EXPECT_EQ(r.count("nonmanifold_edge"), 1u);
    ASSERT_EQ(defect(r, "nonmanifold_edge").where.size(), 1u);
    EXPECT_EQ(defect(r, "nonmanifold_edge").where[0], (Vec3{1, 1, 0.5}));
    EXPECT_EQ(defect(r, "nonmanifold_node").examples, (Ids{3, 7}));  // (1,1,0) and (1,1,1)
}

TEST(Validate, VertexWhereTwoCubesTouchIsAPinch) {
    const HexMesh m = weld(unitCube(), unitCube({1, 1, 1}));
    ASSERT_EQ(m.nodes.size(), 15u);
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), std::set<std::string>{"nonmanifold_node"}) << toJson(r).dump();
    EXPECT_EQ(defect(r, "nonmanifold_node").examples, Ids{7});  // (1,1,1)
    ASSERT_EQ(defect(r, "nonmanifold_node").where.size(), 1u);
    EXPECT_EQ(defect(r, "nonmanifold_node").where[0], (Vec3{1, 1, 1}));
}

TEST(Validate, InterfaceEdgeInsideTheMeshIsCheckedPerSurface) {
    // A 2x2x3 block of material 3 whose middle layer is a checkerboard of
    // materials 1 and 2. The middle layer's vertical centre edge touches no
    // exterior, yet the 1|2 interface has four quads on it: material 1 touches
    // itself only along that edge. Its two end nodes are pinches of the 1|3 and
    // 2|3 interfaces.
    HexMesh m = makeBlock(2, 2, 3);
    for (auto& mat : m.material) mat = 3;
    m.material[4] = m.material[7] = 1;  // (0,0) and (1,1) of the middle layer
    m.material[5] = m.material[6] = 2;
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), (std::set<std::string>{"nonmanifold_edge", "nonmanifold_node"})) << toJson(r).dump();
    EXPECT_EQ(r.count("nonmanifold_edge"), 1u);
    ASSERT_EQ(defect(r, "nonmanifold_edge").where.size(), 1u);
    EXPECT_EQ(defect(r, "nonmanifold_edge").where[0], (Vec3{1, 1, 1.5}));
    EXPECT_EQ(defect(r, "nonmanifold_node").examples,
              (Ids{blockNode(2, 2, 1, 1, 1), blockNode(2, 2, 1, 1, 2)}));
}

TEST(Validate, FoldedNeighbourIsInconsistentlyOrientedButNotInverted) {
    // Orientation isolated from inversion: the second hex is a positive hex of
    // height 0.5 hanging from the first one's top face into the first one. Both
    // Jacobians are positive, but both hexes lie below the shared face, so they
    // traverse it in the same direction.
    HexMesh m = unitCube();
    const auto shared = topFace(m, 0);
    m.addHex(hexOf(addSquare(m, 0.5), shared));
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), std::set<std::string>{"inconsistent_orientation"}) << toJson(r).dump();
    EXPECT_EQ(r.count("inconsistent_orientation"), 1u);
    ASSERT_EQ(defect(r, "inconsistent_orientation").where.size(), 1u);
    EXPECT_EQ(defect(r, "inconsistent_orientation").where[0], (Vec3{0.5, 0.5, 1.0}));
}

TEST(Validate, MirroredHexIsInvertedAndInconsistentlyOriented) {
    // Listing a hex's top face first mirrors it: same place, left-handed node
    // order. That is both an inversion and a misorientation of the shared quad.
    HexMesh m = makeBlock(1, 1, 2);
    const Hex h = m.hexes[1];
    m.hexes[1] = {h[4], h[5], h[6], h[7], h[0], h[1], h[2], h[3]};
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), (std::set<std::string>{"inverted_hex", "inconsistent_orientation"})) << toJson(r).dump();
    EXPECT_EQ(defect(r, "inverted_hex").examples, Ids{1});
    EXPECT_EQ(r.count("inconsistent_orientation"), 1u);
}

TEST(Validate, NodeMovedThroughTheOppositeFaceInvertsItsHex) {
    HexMesh m = makeBlock(2, 1, 1);
    m.nodes[blockNode(2, 1, 2, 1, 1)] = {2, 1, -0.5};  // top corner of hex 1 pushed below its bottom
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), std::set<std::string>{"inverted_hex"}) << toJson(r).dump();
    EXPECT_EQ(defect(r, "inverted_hex").examples, Ids{1});
    EXPECT_EQ(defect(r, "inverted_hex").constraint, "N");
}

TEST(Validate, HexTwistedHalfATurnIsInvertedAtItsCentre) {
    // Top face turned 180 degrees about the vertical axis: every corner keeps a
    // positive determinant, but the xi and eta axes cancel at the centre.
    HexMesh m = unitCube();
    const Hex h = m.hexes[0];
    m.hexes[0] = {h[0], h[1], h[2], h[3], h[6], h[7], h[4], h[5]};
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), std::set<std::string>{"inverted_hex"}) << toJson(r).dump();
    EXPECT_EQ(defect(r, "inverted_hex").examples, Ids{0});
}

TEST(Validate, UnusedNodeIsReported) {
    HexMesh m = unitCube();
    m.addNode({5, 5, 5});
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), std::set<std::string>{"unused_node"});
    EXPECT_EQ(defect(r, "unused_node").examples, Ids{8});
    EXPECT_EQ(defect(r, "unused_node").where, std::vector<Vec3>{(Vec3{5, 5, 5})});
}

TEST(Validate, CubesWithTheirOwnCopiesOfSharedNodesAreDisconnected) {
    // Two cubes side by side, each with its own 8 nodes (an exporter that did
    // not merge nodes): every face is a boundary face and nothing else is wrong.
    HexMesh m = unitCube();
    const HexMesh right = unitCube({1, 0, 0});
    Hex h = right.hexes[0];
    for (Index& v : h) v += static_cast<Index>(m.nodes.size());
    for (const Vec3& p : right.nodes) m.addNode(p);
    m.addHex(h);
    m.nodes[h[0]][1] += 1e-12;  // a copy that differs in its last bits counts too
    const ValidityReport r = validate(m);
    EXPECT_EQ(keys(r), std::set<std::string>{"coincident_node"}) << toJson(r).dump();
    EXPECT_EQ(r.count("coincident_node"), 8u);
    EXPECT_NE(defect(r, "coincident_node").description.find("disconnected"), std::string::npos);
    // merged, the same two cubes are valid
    EXPECT_TRUE(validate(makeBlock(2, 1, 1)).ok());
}

// ------------------------------------------------------------ the report

TEST(Validate, ExamplesAreTheSmallestIdsAndAtMostTen) {
    // 22 unused nodes first, then the 8 nodes of one hex.
    HexMesh m;
    for (int i = 0; i < 22; ++i) m.addNode({10.0 + i, 0, 0});
    const HexMesh cube = unitCube();
    for (const Vec3& p : cube.nodes) m.addNode(p);
    Hex h = cube.hexes[0];
    for (Index& v : h) v += 22;
    m.addHex(h);
    const ValidityReport r = validate(m);
    EXPECT_EQ(r.count("unused_node"), 22u);
    EXPECT_EQ(defect(r, "unused_node").examples, (Ids{0, 1, 2, 3, 4, 5, 6, 7, 8, 9}));
    EXPECT_EQ(defect(r, "unused_node").where.size(), kMaxExamples);
}

TEST(Validate, ToJsonOfAValidMeshIsOkWithNoDefects) {
    EXPECT_EQ(toJson(validate(unitCube())), nlohmann::json::parse(R"({"ok": true, "defects": {}})"));
}

TEST(Validate, ToJsonListsEveryDefectWithItsCountAndExamples) {
    HexMesh m = makeBlock(2, 1, 1);
    m.nodes[blockNode(2, 1, 2, 1, 1)] = {2, 1, -0.5};
    m.addNode({7, 8, 9});
    const nlohmann::json j = toJson(validate(m));
    EXPECT_EQ(j["ok"], false);
    ASSERT_EQ(j["defects"].size(), 2u);
    for (const char* key : {"inverted_hex", "unused_node"}) {
        const nlohmann::json& d = j["defects"][key];
        for (const char* field : {"constraint", "description", "count", "entity", "examples", "where"})
            EXPECT_TRUE(d.contains(field)) << key << "." << field;
        EXPECT_EQ(d["count"], 1);
    }
    EXPECT_EQ(j["defects"]["unused_node"]["constraint"], "A");
    EXPECT_EQ(j["defects"]["unused_node"]["entity"], "node");
    EXPECT_EQ(j["defects"]["unused_node"]["examples"], nlohmann::json::parse("[12]"));
    EXPECT_EQ(j["defects"]["unused_node"]["where"], nlohmann::json::parse("[[7.0, 8.0, 9.0]]"));
    EXPECT_EQ(j["defects"]["inverted_hex"]["examples"], nlohmann::json::parse("[1]"));
}

TEST(Validate, ResultDoesNotDependOnTheThreadCount) {
    // Enough hexes for TBB to split every loop, and more defects than examples.
    HexMesh m = makeBlock(24, 24, 24);
    for (std::size_t v = 0; v < m.nodes.size(); v += 97) m.nodes[v][2] += 3.0;  // inverts hexes around v
    for (int i = 0; i < 15; ++i) m.addNode({-1.0 - i, 0, 0});
    m.addHex(m.hexes[500]);
    nlohmann::json one, all;
    {
        tbb::global_control serial(tbb::global_control::max_allowed_parallelism, 1);
        one = toJson(validate(m));
    }
    all = toJson(validate(m));
    EXPECT_EQ(one, all);
    EXPECT_GT(one["defects"]["inverted_hex"]["count"].get<std::size_t>(), kMaxExamples);
}

// validate() builds no quads or edges of the volume, yet names them by the
// ids buildTopology gives them: each example's id, read in the full
// topology, is a quad or edge at the place the report gives.
TEST(Validate, QuadAndEdgeIdsAreTheFullTopologys) {
    HexMesh book = unitCube();
    book.addHex(hexOf(topFace(book, 0), addSquare(book, 2.0)));
    book.addHex(hexOf(topFace(book, 0), addSquare(book, 1.5)));
    HexMesh mirrored = makeBlock(2, 1, 2);
    const Hex h = mirrored.hexes[1];
    mirrored.hexes[1] = {h[4], h[5], h[6], h[7], h[0], h[1], h[2], h[3]};
    mirrored.addNode({5, 5, 5});
    HexMesh wedge = makeBlock(2, 2, 1);
    wedge.hexes[3][6] = wedge.hexes[3][7];
    HexMesh crack = makeBlock(2, 2, 2);
    crack.hexes[1][0] = crack.addNode(crack.nodes[blockNode(2, 2, 1, 0, 0)]);
    auto mid = [](const HexMesh& m, auto ids) {
        Vec3 c{0, 0, 0};
        for (Index v : ids)
            for (int d = 0; d < 3; ++d) c[d] += m.nodes[v][d] / static_cast<double>(ids.size());
        return c;
    };
    std::set<std::string> kinds;
    for (const HexMesh& m : {book, mirrored, wedge, crack, weld(unitCube(), unitCube({1, 1, 0}))}) {
        const ValidityReport r = validate(m);
        EXPECT_FALSE(r.ok());
        const Topology all = buildTopology(m);
        for (const auto& [key, d] : r.defects) {
            if (d.entity != "quad" && d.entity != "edge") continue;
            kinds.insert(key);
            ASSERT_EQ(d.examples.size(), d.where.size()) << key;
            for (std::size_t i = 0; i < d.examples.size(); ++i) {
                const auto id = static_cast<std::size_t>(d.examples[i]);
                const Vec3 at = d.entity == "quad" ? mid(m, all.quads.at(id).nodes) : mid(m, all.edges.at(id));
                for (int k = 0; k < 3; ++k) EXPECT_NEAR(at[k], d.where[i][k], 1e-12) << key << " example " << id;
            }
        }
        if (r.count("overfull_quad")) EXPECT_EQ(defect(r, "overfull_quad").examples, all.overfullQuads);
    }
    EXPECT_EQ(kinds, (std::set<std::string>{"inconsistent_orientation", "nonmanifold_edge", "overfull_quad",
                                             "quad_doublet"}));
}

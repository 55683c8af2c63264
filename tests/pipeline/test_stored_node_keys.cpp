// The node keys a kept mesh stores for meshing it again locally
// (StoredNodeKeys.hpp): they expand to exactly the keys contourKeys and
// addCopyKeys give, every key finds its node (the lowest where several share
// it) and a key no node has finds none, in a small fraction of their size on
// real meshes.
#include <gtest/gtest.h>

#include <algorithm>
#include <iostream>
#include <string>
#include <vector>

#include "isohex/core/Error.hpp"
#include "isohex/pipeline/Contour.hpp"
#include "isohex/pipeline/LocalRetry.hpp"
#include "isohex/pipeline/Pillow.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/StoredNodeKeys.hpp"

#include "ExtractionChecks.hpp"

namespace isohex::pipeline {
namespace {

isohex::PillowResult pass(Index firstNewNode, std::vector<Index> copyOf) {
    isohex::PillowResult r;
    r.firstNewNode = firstNewNode;
    r.copyOf = std::move(copyOf);
    return r;
}

// Every key finds the lowest node that has it.
void expectEveryKeyFound(const StoredNodeKeys& stored, const std::vector<NodeKey>& keys) {
    for (std::size_t v = 0; v < keys.size(); ++v) {
        const auto first = std::find(keys.begin(), keys.end(), keys[v]) - keys.begin();
        EXPECT_EQ(stored.find(keys[v]), static_cast<Index>(first)) << "node " << v;
    }
}

std::vector<NodeKey> withCopies(std::vector<NodeKey> keys, const std::vector<isohex::PillowResult>& passes,
                                const std::vector<std::int32_t>& materials) {
    addCopyKeys(keys, passes, materials);
    return keys;
}

TEST(StoredNodeKeys, AscendingKeysExpandToTheKeysAndTheirSheets) {
    const std::vector<NodeKey> contoured{{3, 0}, {4, 0}, {9, 0}, {64, 0}, {65, 0}, {130, 0}};
    const std::vector<isohex::PillowResult> passes{pass(6, {0, 3, 5}), pass(9, {1, 3})};
    const std::vector<std::int32_t> materials{2, 7};
    StoredNodeKeys stored(contoured, 131);
    stored.addSheets(passes, materials);
    EXPECT_EQ(stored.size(), 11u);
    const std::vector<NodeKey> want = withCopies(contoured, passes, materials);
    EXPECT_EQ(stored.expand(), want);
    EXPECT_EQ(want[6], (NodeKey{3, 3}));
    EXPECT_EQ(want[10], (NodeKey{64, 8}));
    expectEveryKeyFound(stored, want);
    for (const NodeKey& missing : {NodeKey{5, 0}, NodeKey{63, 0}, NodeKey{131, 0}, NodeKey{-1, 0}, NodeKey{4, 3},
                                   NodeKey{9, 8}, NodeKey{3, 5}, NodeKey{130, 9}})
        EXPECT_EQ(stored.find(missing), kNone) << missing.cell << " " << missing.sheet;
}

TEST(StoredNodeKeys, KeysOutOfOrderAreKeptAsTheyAre) {
    // (a vertex outside its cell would give such keys; so would a repeated cell)
    for (const std::vector<NodeKey>& contoured : {std::vector<NodeKey>{{5, 0}, {2, 0}, {7, 0}},
                                                   std::vector<NodeKey>{{2, 0}, {2, 0}, {7, 0}},
                                                   std::vector<NodeKey>{{2, 0}, {9, 0}, {70, 0}}}) {
        StoredNodeKeys stored(contoured, 10);  // the last: a cell beyond the grid given
        stored.addSheets({pass(3, {2, 0})}, {1});
        const std::vector<NodeKey> want = withCopies(contoured, {pass(3, {2, 0})}, {1});
        EXPECT_EQ(stored.expand(), want);
        expectEveryKeyFound(stored, want);
        EXPECT_EQ(stored.find({3, 0}), kNone);
        EXPECT_EQ(stored.find({contoured[1].cell, 3}), kNone);  // no such sheet
    }
}

TEST(StoredNodeKeys, RefusesSheetsThatDoNotFollowTheNodes) {
    StoredNodeKeys stored({{1, 0}, {2, 0}}, 4);
    EXPECT_THROW(stored.addSheets({pass(3, {0})}, {1}), Error);  // numbered past a gap
    EXPECT_THROW(stored.addSheets({pass(2, {0}), pass(3, {2})}, {1, 2}), Error);  // a copy of a copy
    EXPECT_THROW(stored.addSheets({pass(2, {0})}, {}), Error);  // a sheet without its material
    EXPECT_THROW(stored.addSheets({pass(2, {0}), pass(3, {1})}, {4, 2}), Error);  // materials not ascending
}

// As meshLabels contours and pillows: the stored keys expand to the keys,
// and the contoured ones ascend (so they take the compact form).
void checkRealMesh(const std::string& input, MeshSettings settings) {
    testsupport::QuietSink sink;
    const Prepared p = prepare(input, settings, sink);
    HeldBack heldBack;
    HexMesh mesh = contour(p, settings, sink, nullptr, &heldBack);
    std::vector<NodeKey> keys = contouredKeys(mesh, p);
    StoredNodeKeys stored = storedContouredKeys(mesh, p);
    std::vector<isohex::PillowResult> passes;
    pillowBoundary(mesh, settings, sink, &passes, &heldBack);
    addCopyKeys(keys, passes, sortedMaterials(mesh));
    addSheetKeys(stored, passes, mesh, settings);
    ASSERT_EQ(keys.size(), mesh.nodeCount());
    ASSERT_EQ(stored.size(), mesh.nodeCount());
    EXPECT_EQ(stored.expand(), keys) << input;
    for (std::size_t v = 0; v < keys.size(); ++v) ASSERT_EQ(stored.find(keys[v]), static_cast<Index>(v)) << input;
    // kept as they are, the contoured keys alone would take half the keys' size
    EXPECT_LT(stored.bytes(), mesh.nodeCount() * sizeof(NodeKey) / 3)
        << input << ": " << stored.bytes() << " bytes for " << mesh.nodeCount() << " nodes";
    std::cout << "[figures] " << input << ": " << mesh.nodeCount() << " nodes, keys stored in " << stored.bytes()
              << " bytes (" << mesh.nodeCount() * sizeof(NodeKey) << " as NodeKeys)\n";
}

TEST(StoredNodeKeys, ExpandToTheKeysOfRealMeshes) {
    checkRealMesh(testsupport::phantoms() + "/sphere.nii.gz", testsupport::intensity(50.0, 1.5));
    checkRealMesh(testsupport::phantoms() + "/two_materials.nii.gz", testsupport::labels());
    MeshSettings jhu = testsupport::labels();
    jhu.size = 3.0;
    checkRealMesh(testsupport::sharedData() + "/JHU-WhiteMatter-labels-2mm.nii.gz", jhu);
}

}  // namespace
}  // namespace isohex::pipeline

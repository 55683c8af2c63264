#pragma once
// The node keys (Part.hpp's NodeKey) of a mesh kept for meshing it again
// locally (LocalRetry.hpp), stored compactly while the optimiser runs and
// looked up without being expanded: the contoured nodes are numbered in cell
// order, so their keys ascend and one bit per grid cell (with a running count
// per 64 cells) says which cells carry one and which node it is; a sheet's
// copies are their originals' keys with the sheet's number, so a list of
// (original, copy) pairs holds them. About 0.19 bytes per grid cell plus 8
// per copy, against 16 bytes per node for the keys themselves and 24 more
// per node for a sorted table to look them up (ch2bet at 1 mm, 2.0 M nodes:
// 33 + 48 MB that way). Contoured keys that do not ascend are kept sorted
// with their nodes instead.
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "isohex/core/Pillow.hpp"
#include "isohex/pipeline/Part.hpp"

namespace isohex::pipeline {

class StoredNodeKeys {
public:
    StoredNodeKeys() = default;
    // The keys of the contoured nodes (sheet 0, in node order), each cell an
    // index below `gridCells`.
    StoredNodeKeys(const std::vector<NodeKey>& contoured, std::size_t gridCells);

    // Appends the sheets pillowed after (pillowBoundary's passes, one per
    // material of the ascending `materials`), as addCopyKeys does; throws
    // isohex::Error where a pass does not number its copies right after the
    // nodes stored so far, or copies a copy.
    void addSheets(const std::vector<isohex::PillowResult>& passes, const std::vector<std::int32_t>& materials);

    std::size_t size() const { return size_; }
    bool empty() const { return size_ == 0; }
    // The memory the stored keys take, in bytes.
    std::size_t bytes() const;

    // The node with key `key` (the lowest one if several have it), or kNone.
    Index find(const NodeKey& key) const;

    // Every node's key, in node order (what contourKeys and addCopyKeys gave).
    std::vector<NodeKey> expand() const;

private:
    struct Sheet {
        std::int32_t sheet = 0;
        Index first = 0;                              // the node of its first copy
        std::vector<std::pair<Index, Index>> copies;  // (original, copy - first), ascending
    };
    Index contouredNode(std::int64_t cell) const;

    std::size_t contoured_ = 0, size_ = 0;
    std::vector<std::uint64_t> cellBits_;  // ascending keys: bit c set when cell c carries a node
    std::vector<std::uint32_t> before_;    // per word of cellBits_, the set bits in the words before it
    std::vector<std::pair<std::int64_t, Index>> cells_;  // otherwise: (cell, node), ascending
    std::vector<Sheet> sheets_;                          // ascending sheet numbers
};

}  // namespace isohex::pipeline

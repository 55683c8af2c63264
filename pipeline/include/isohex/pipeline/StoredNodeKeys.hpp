#pragma once
// The node keys (Part.hpp's NodeKey) of a mesh kept for meshing it again
// locally (LocalRetry.hpp), stored compactly while the optimiser runs: the
// contoured nodes are numbered in cell order, so their keys ascend and one
// bit per grid cell says which cells carry one; a sheet's copies are their
// originals' keys with the sheet's number, so the copy-of list holds them.
// About 0.15 bytes per grid cell plus 4 per copy, against 16 bytes per node
// for the keys themselves (ch2bet at 1 mm: 2 MB instead of 33 MB at the
// job's peak). Contoured keys that do not ascend are kept as they are.
#include <cstddef>
#include <cstdint>
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
    // nodes stored so far.
    void addSheets(const std::vector<isohex::PillowResult>& passes, const std::vector<std::int32_t>& materials);

    std::size_t size() const;
    bool empty() const { return size() == 0; }
    // The memory the stored keys take, in bytes.
    std::size_t bytes() const;

    // Every node's key, in node order (what contourKeys and addCopyKeys gave).
    std::vector<NodeKey> expand() const;

private:
    struct Sheet {
        std::int32_t sheet = 0;
        std::vector<Index> copyOf;  // per copy, the contoured node it copies
    };
    std::size_t contoured_ = 0;
    std::vector<std::uint64_t> cellBits_;  // ascending keys: bit c set when cell c carries a node
    std::vector<std::int64_t> cells_;      // otherwise: each contoured node's cell
    std::vector<Sheet> sheets_;
};

}  // namespace isohex::pipeline

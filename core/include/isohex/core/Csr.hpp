#pragma once
// Compressed rows (CSR): the adjacency lists of topology, the dual and the
// sheet operations.
#include <cstddef>
#include <vector>

#include "isohex/core/HexMesh.hpp"

namespace isohex {

// The items of row r are items[offsets[r] .. offsets[r+1]). `Storage` is the
// vector type of both arrays (std::vector, or BigVec for large temporaries).
template <class Storage>
struct CsrOf {
    Storage offsets;  // rows + 1 entries
    Storage items;
    std::size_t rows() const { return offsets.empty() ? 0 : offsets.size() - 1; }
    std::size_t size(std::size_t r) const { return static_cast<std::size_t>(offsets[r + 1] - offsets[r]); }
    const Index* begin(std::size_t r) const { return items.data() + offsets[r]; }
    const Index* end(std::size_t r) const { return items.data() + offsets[r + 1]; }
};

using Csr = CsrOf<std::vector<Index>>;

}  // namespace isohex

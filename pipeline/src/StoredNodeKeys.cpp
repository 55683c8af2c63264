#include "isohex/pipeline/StoredNodeKeys.hpp"

#include <string>

#include "isohex/core/Error.hpp"

namespace isohex::pipeline {

namespace {

bool ascendingOnSheetZero(const std::vector<NodeKey>& keys, std::size_t gridCells) {
    for (std::size_t v = 0; v < keys.size(); ++v) {
        const NodeKey& k = keys[v];
        if (k.sheet != 0 || k.cell < 0 || static_cast<std::size_t>(k.cell) >= gridCells) return false;
        if (v > 0 && !(keys[v - 1].cell < k.cell)) return false;
    }
    return true;
}

}  // namespace

StoredNodeKeys::StoredNodeKeys(const std::vector<NodeKey>& contoured, std::size_t gridCells)
    : contoured_(contoured.size()) {
    if (!ascendingOnSheetZero(contoured, gridCells)) {
        for (const NodeKey& k : contoured) {
            if (k.sheet != 0) throw Error("stored node keys: a contoured node has a sheet key (please report this)");
            cells_.push_back(k.cell);
        }
        return;
    }
    cellBits_.assign((gridCells + 63) / 64, 0);
    for (const NodeKey& k : contoured) {
        const auto c = static_cast<std::size_t>(k.cell);
        cellBits_[c / 64] |= std::uint64_t{1} << (c % 64);
    }
}

void StoredNodeKeys::addSheets(const std::vector<isohex::PillowResult>& passes, const std::vector<std::int32_t>& materials) {
    if (passes.size() > materials.size())
        throw Error("stored node keys: " + std::to_string(passes.size()) + " sheets for " +
                    std::to_string(materials.size()) + " materials (please report this)");
    for (std::size_t p = 0; p < passes.size(); ++p) {
        const isohex::PillowResult& r = passes[p];
        if (static_cast<std::size_t>(r.firstNewNode) != size())
            throw Error("stored node keys: the sheets' copies are not numbered after the nodes they copy");
        for (Index original : r.copyOf)
            if (original < 0 || static_cast<std::size_t>(original) >= contoured_)
                throw Error("stored node keys: a sheet copied a copied node (please report this)");
        sheets_.push_back({materials[p] + 1, r.copyOf});
    }
}

std::size_t StoredNodeKeys::size() const {
    std::size_t n = contoured_;
    for (const Sheet& s : sheets_) n += s.copyOf.size();
    return n;
}

std::size_t StoredNodeKeys::bytes() const {
    std::size_t b = cellBits_.capacity() * sizeof(std::uint64_t) + cells_.capacity() * sizeof(std::int64_t);
    for (const Sheet& s : sheets_) b += sizeof(Sheet) + s.copyOf.capacity() * sizeof(Index);
    return b;
}

std::vector<NodeKey> StoredNodeKeys::expand() const {
    std::vector<NodeKey> keys;
    keys.reserve(size());
    if (!cellBits_.empty() || cells_.empty()) {
        for (std::size_t w = 0; w < cellBits_.size(); ++w)
            for (std::uint64_t bits = cellBits_[w]; bits != 0; bits &= bits - 1)
                keys.push_back({static_cast<std::int64_t>(w * 64 + static_cast<std::size_t>(__builtin_ctzll(bits))), 0});
    } else {
        for (std::int64_t c : cells_) keys.push_back({c, 0});
    }
    for (const Sheet& s : sheets_)
        for (Index original : s.copyOf) keys.push_back({keys[static_cast<std::size_t>(original)].cell, s.sheet});
    return keys;
}

}  // namespace isohex::pipeline

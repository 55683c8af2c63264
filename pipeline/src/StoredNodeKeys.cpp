#include "isohex/pipeline/StoredNodeKeys.hpp"

#include <algorithm>
#include <bit>
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
    : contoured_(contoured.size()), size_(contoured.size()) {
    if (!ascendingOnSheetZero(contoured, gridCells)) {
        for (std::size_t v = 0; v < contoured.size(); ++v) {
            if (contoured[v].sheet != 0)
                throw Error("stored node keys: a contoured node has a sheet key (please report this)");
            cells_.emplace_back(contoured[v].cell, static_cast<Index>(v));
        }
        std::sort(cells_.begin(), cells_.end());
        return;
    }
    cellBits_.assign((gridCells + 63) / 64, 0);
    for (const NodeKey& k : contoured) {
        const auto c = static_cast<std::size_t>(k.cell);
        cellBits_[c / 64] |= std::uint64_t{1} << (c % 64);
    }
    before_.resize(cellBits_.size());
    std::uint32_t count = 0;
    for (std::size_t w = 0; w < cellBits_.size(); ++w) {
        before_[w] = count;
        count += static_cast<std::uint32_t>(std::popcount(cellBits_[w]));
    }
}

void StoredNodeKeys::addSheets(const std::vector<isohex::PillowResult>& passes,
                               const std::vector<std::int32_t>& materials) {
    if (passes.size() > materials.size())
        throw Error("stored node keys: " + std::to_string(passes.size()) + " sheets for " +
                    std::to_string(materials.size()) + " materials (please report this)");
    for (std::size_t p = 0; p < passes.size(); ++p) {
        const isohex::PillowResult& r = passes[p];
        if (static_cast<std::size_t>(r.firstNewNode) != size_)
            throw Error("stored node keys: the sheets' copies are not numbered after the nodes they copy");
        const std::int32_t sheet = materials[p] + 1;
        if (!sheets_.empty() && !(sheets_.back().sheet < sheet))
            throw Error("stored node keys: the sheets are not in ascending material order (please report this)");
        Sheet s{sheet, r.firstNewNode, {}};
        s.copies.reserve(r.copyOf.size());
        for (std::size_t j = 0; j < r.copyOf.size(); ++j) {
            const Index original = r.copyOf[j];
            if (original < 0 || static_cast<std::size_t>(original) >= contoured_)
                throw Error("stored node keys: a sheet copied a copied node (please report this)");
            s.copies.emplace_back(original, static_cast<Index>(j));
        }
        std::sort(s.copies.begin(), s.copies.end());
        size_ += r.copyOf.size();
        sheets_.push_back(std::move(s));
    }
}

std::size_t StoredNodeKeys::bytes() const {
    std::size_t b = cellBits_.capacity() * sizeof(std::uint64_t) + before_.capacity() * sizeof(std::uint32_t) +
                    cells_.capacity() * sizeof(cells_[0]);
    for (const Sheet& s : sheets_) b += sizeof(Sheet) + s.copies.capacity() * sizeof(s.copies[0]);
    return b;
}

Index StoredNodeKeys::contouredNode(std::int64_t cell) const {
    if (!cellBits_.empty()) {
        if (cell < 0 || static_cast<std::size_t>(cell) >= cellBits_.size() * 64) return kNone;
        const auto c = static_cast<std::size_t>(cell);
        const std::uint64_t word = cellBits_[c / 64], bit = std::uint64_t{1} << (c % 64);
        if (!(word & bit)) return kNone;
        return static_cast<Index>(before_[c / 64] + static_cast<std::uint32_t>(std::popcount(word & (bit - 1))));
    }
    const auto it = std::lower_bound(cells_.begin(), cells_.end(), std::make_pair(cell, Index{-1}));
    return it != cells_.end() && it->first == cell ? it->second : kNone;
}

Index StoredNodeKeys::find(const NodeKey& key) const {
    const Index original = contouredNode(key.cell);
    if (original == kNone || key.sheet == 0) return original;
    const auto s = std::lower_bound(sheets_.begin(), sheets_.end(), key.sheet,
                                    [](const Sheet& a, std::int32_t sheet) { return a.sheet < sheet; });
    if (s == sheets_.end() || s->sheet != key.sheet) return kNone;
    const auto c = std::lower_bound(s->copies.begin(), s->copies.end(), std::make_pair(original, Index{-1}));
    return c != s->copies.end() && c->first == original ? s->first + c->second : kNone;
}

std::vector<NodeKey> StoredNodeKeys::expand() const {
    std::vector<NodeKey> keys(size_);
    if (!cellBits_.empty()) {
        std::size_t v = 0;
        for (std::size_t w = 0; w < cellBits_.size(); ++w)
            for (std::uint64_t bits = cellBits_[w]; bits != 0; bits &= bits - 1)
                keys[v++] = {static_cast<std::int64_t>(w * 64 + static_cast<std::size_t>(std::countr_zero(bits))), 0};
    } else {
        for (const auto& [cell, node] : cells_) keys[static_cast<std::size_t>(node)] = {cell, 0};
    }
    for (const Sheet& s : sheets_)
        for (const auto& [original, j] : s.copies)
            keys[static_cast<std::size_t>(s.first + j)] = {keys[static_cast<std::size_t>(original)].cell, s.sheet};
    return keys;
}

}  // namespace isohex::pipeline

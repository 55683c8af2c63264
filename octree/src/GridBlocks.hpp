#pragma once
// The 2x2x2 blocks of grid points (private to octree/): whether every
// material's region (and the interfaces between materials) is manifold in a
// block, and a block's share of each material boundary's Euler characteristic.
// The non-manifold repair and the topology matching both judge blocks so.
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "isohex/octree/Labels.hpp"

namespace isohex::octree {

// Corner b of a 2x2x2 block is offset (b & 1, b >> 1 & 1, b >> 2 & 1).
// kManifold[p]: the corners in bit set p, and those not in it, are each empty
// or 6-connected inside the block (corners adjacent when they differ in one bit).
struct ManifoldTable {
    std::array<bool, 256> ok{};
    // how far from manifold: 1 for the set and 1 for its complement when not
    // 6-connected inside the block (a repair step that mends one side counts)
    std::array<int, 256> pieces{};
    ManifoldTable() {
        auto connected = [](unsigned set) {
            if (set == 0) return true;
            unsigned seen = set & (~set + 1), frontier = seen;
            while (frontier) {
                unsigned next = 0;
                for (int b = 0; b < 8; ++b)
                    if (frontier >> b & 1)
                        for (int d = 0; d < 3; ++d) {
                            const unsigned nb = 1u << (b ^ (1 << d));
                            if ((set & nb) && !(seen & nb)) next |= nb;
                        }
                seen |= next;
                frontier = next;
            }
            return seen == set;
        };
        for (unsigned p = 0; p < 256; ++p) {
            ok[p] = connected(p) && connected(~p & 0xFFu);
            pieces[p] = !connected(p) + !connected(~p & 0xFFu);
        }
    }
};
extern const ManifoldTable kTable;

struct BlockView {
    std::array<std::size_t, 8> point;
    std::array<std::int32_t, 8> mat;
};

inline BlockView block(const Labels& l, int i, int j, int k) {
    BlockView b;
    for (int c = 0; c < 8; ++c) {
        b.point[c] = l.grid.index(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1));
        b.mat[c] = l.material[b.point[c]];
    }
    return b;
}

// With three or more materials in a block, each interface between two of them
// must also be one fan around the block centre: the block edges joining an
// a-point to a b-point are the interface's faces there, and two of them are
// joined across a block square holding exactly two such edges.
int badPairs(const std::array<std::int32_t, 8>& mat);

// Sums score(pattern) over the materials of a block, where pattern has bit d
// set for the corners d holding that material.
template <class Score>
int sumOverMaterials(const std::array<std::int32_t, 8>& mat, Score score) {
    int sum = 0;
    for (int c = 0; c < 8; ++c) {
        bool first = true;
        for (int d = 0; d < c; ++d)
            if (mat[d] == mat[c]) first = false;
        if (!first) continue;
        unsigned p = 0;
        for (int d = 0; d < 8; ++d)
            if (mat[d] == mat[c]) p |= 1u << d;
        sum += score(p);
    }
    return sum;
}

inline int badMaterials(const std::array<std::int32_t, 8>& mat) {
    return sumOverMaterials(mat, [](unsigned p) { return kTable.ok[p] ? 0 : 1; }) + badPairs(mat);
}

inline bool blockManifold(const std::array<std::int32_t, 8>& mat) { return badMaterials(mat) == 0; }

// As badMaterials, but a material whose points and whose complement are both
// split inside the block counts twice: zero exactly when badMaterials is.
inline int badness(const std::array<std::int32_t, 8>& mat) {
    return sumOverMaterials(mat, [](unsigned p) { return static_cast<int>(kTable.pieces[p]); }) + badPairs(mat);
}

inline bool uniformBlock(const std::array<std::int32_t, 8>& mat) {
    for (int c = 1; c < 8; ++c)
        if (mat[c] != mat[0]) return false;
    return true;
}

// The contributions of a non-uniform block to the Euler characteristic of
// each material's boundary (the union of the closed cubes around its
// points), with every point pair, square and block counted at the block
// whose lowest corner is its lowest point: add(material, delta, wholeBlock)
// for the lowest corner's three pairs (+1 for each material of a pair that
// differs), its three squares there and the block itself (-1 and +1 for each
// material present but not everywhere; wholeBlock for the block's own).
// Background (0) gets nothing.
template <class Add>
void forBlockEuler(const std::array<std::int32_t, 8>& mat, Add add) {
    // corner c of the block is offset (c & 1, c >> 1 & 1, c >> 2 & 1)
    for (int d = 0; d < 3; ++d) {
        const std::int32_t a = mat[0], o = mat[1 << d];
        if (a == o) continue;
        if (a != 0) add(a, 1, false);
        if (o != 0) add(o, 1, false);
    }
    auto mixed = [&](const std::int32_t* m, int n, int d, bool wholeBlock) {
        for (int c = 0; c < n; ++c) {
            if (m[c] == 0) continue;
            bool first = true, all = true;
            for (int e = 0; e < c; ++e) first = first && m[e] != m[c];
            for (int e = 0; e < n; ++e) all = all && m[e] == m[c];
            if (first && !all) add(m[c], d, wholeBlock);
        }
    };
    const std::int32_t sq[3][4] = {{mat[0], mat[1], mat[2], mat[3]},   // xy
                                   {mat[0], mat[1], mat[4], mat[5]},   // xz
                                   {mat[0], mat[2], mat[4], mat[6]}};  // yz
    for (const auto& q : sq) mixed(q, 4, -1, false);
    mixed(mat.data(), 8, 1, true);
}

// Lowest-corner indices of the non-manifold blocks, sorted.
std::vector<std::size_t> badBlocks(const Labels& l);

// The non-manifold blocks among `candidates` (lowest-corner indices), sorted.
std::vector<std::size_t> badBlocksAmong(const Labels& l, std::vector<std::size_t> candidates);

}  // namespace isohex::octree

// Connected regions of grid points and the topology of their boundaries.
#include <algorithm>
#include <map>
#include <sstream>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "GridBlocks.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/Regions.hpp"

namespace isohex::octree {

DisjointSets<std::uint32_t> materialRegions(const Labels& labels, Adjacency adjacency) {
    // The neighbours after a point in x-fastest order, as offsets q of the
    // 3x3x3 block around it (q = 13 + dx + 3 dy + 9 dz): +x, +y, +z for
    // Face, all 13 for Full.
    static constexpr int kFace[] = {14, 16, 22};
    static constexpr int kFull[] = {14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26};
    const int* after = adjacency == Adjacency::Face ? kFace : kFull;
    const int count = adjacency == Adjacency::Face ? 3 : 13;
    const Grid& g = labels.grid;
    const auto [nx, ny, nz] = g.dims;
    DisjointSets<std::uint32_t> sets(labels.material.size());
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t p = g.index(i, j, k);
                const std::int32_t m = labels.material[p];
                if (m == 0) continue;
                for (int n = 0; n < count; ++n) {
                    const int q = after[n];
                    const int x = i + q % 3 - 1, y = j + q / 3 % 3 - 1, z = k + q / 9 - 1;
                    if (!g.contains(x, y, z)) continue;
                    const std::size_t o = g.index(x, y, z);
                    if (labels.material[o] == m) sets.unite(static_cast<std::uint32_t>(p), static_cast<std::uint32_t>(o));
                }
            }
    return sets;
}

std::vector<RegionTopology> regionTopology(const Labels& l) {
    const auto [nx, ny, nz] = l.grid.dims;
    // Every point pair, square and block is counted at the block whose lowest
    // corner is its lowest point; the grid's outer layer is background, so
    // nothing mixed is lost past the last block. Uniform blocks (almost all)
    // are skipped after one look at their corners.
    struct Acc {
        std::map<std::int32_t, RegionTopology> t;
        std::vector<std::pair<std::int32_t, std::size_t>> mixed;  // (material, block)
    };
    tbb::enumerable_thread_specific<Acc> local;
    tbb::parallel_for(tbb::blocked_range<int>(0, std::max(nz - 1, 0)), [&](const tbb::blocked_range<int>& r) {
        Acc& acc = local.local();
        for (int k = r.begin(); k != r.end(); ++k)
            for (int j = 0; j + 1 < ny; ++j)
                for (int i = 0; i + 1 < nx; ++i) {
                    const BlockView b = block(l, i, j, k);
                    if (uniformBlock(b.mat)) continue;
                    forBlockEuler(b.mat, [&](std::int32_t m, int d, bool wholeBlock) {
                        auto& t = acc.t[m];
                        t.material = m;
                        t.euler += d;
                        if (wholeBlock) acc.mixed.emplace_back(m, l.grid.index(i, j, k));
                    });
                }
    });
    std::map<std::int32_t, RegionTopology> out;
    for (std::int32_t m : l.material)
        if (m != 0) {
            auto& t = out[m];
            t.material = m;
            ++t.points;
        }
    std::vector<std::pair<std::int32_t, std::size_t>> mixed;
    for (auto& acc : local) {
        for (auto& [m, t] : acc.t) {
            out[m].material = m;
            out[m].euler += t.euler;
        }
        mixed.insert(mixed.end(), acc.mixed.begin(), acc.mixed.end());
    }
    std::sort(mixed.begin(), mixed.end());
    DisjointSets<std::size_t> sets(mixed.size());
    for (std::size_t n = 0; n < mixed.size(); ++n) {
        const auto [m, b] = mixed[n];
        const int i = static_cast<int>(b % nx), j = static_cast<int>(b / nx % ny), k = static_cast<int>(b / nx / ny);
        // neighbour block in +d shares the square of the block's far face in d
        for (int d = 0; d < 3; ++d) {
            const int ni = i + (d == 0), nj = j + (d == 1), nk = k + (d == 2);
            if (ni + 1 >= nx || nj + 1 >= ny || nk + 1 >= nz) continue;
            bool present = false, all = true;
            for (int c = 0; c < 8; ++c) {
                if (!(c >> d & 1)) continue;
                const std::int32_t mm = l.material[l.grid.index(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1))];
                present = present || mm == m;
                all = all && mm == m;
            }
            if (!present || all) continue;
            const auto it = std::lower_bound(mixed.begin(), mixed.end(), std::make_pair(m, l.grid.index(ni, nj, nk)));
            if (it == mixed.end() || it->first != m) continue;
            const std::size_t other = static_cast<std::size_t>(it - mixed.begin());
            sets.unite(n, other);
        }
    }
    for (std::size_t n = 0; n < mixed.size(); ++n)
        if (sets.isRoot(n)) ++out[mixed[n].first].components;
    std::vector<RegionTopology> v;
    for (auto& [m, t] : out) v.push_back(t);
    return v;
}

std::string describe(const std::vector<RegionTopology>& t) {
    std::ostringstream s;
    for (std::size_t i = 0; i < t.size(); ++i) {
        if (i) s << "; ";
        s << "material " << t[i].material << ": " << t[i].components << " surface component"
          << (t[i].components == 1 ? "" : "s") << ", Euler characteristic " << t[i].euler;
    }
    return s.str();
}

}  // namespace isohex::octree

// Choosing the grid level: LBIE's cell tests and the topology-keeping coarsest level.
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdint>
#include <cmath>
#include <string>

#include <tbb/parallel_for.h>

#include "isohex/core/Error.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/LevelChoice.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/Regions.hpp"

namespace isohex::octree {

namespace {

// The 27 fine labels of a coarse cell (2 fine steps wide), m[a][b][c] with
// a, b, c in {0, 1, 2} the fine offsets from its lowest corner.
struct CoarseCell {
    std::int32_t m[3][3][3];

    // Reads the cell with lowest fine point (i0, j0, k0); false when all 27 agree.
    bool read(const Labels& fine, int i0, int j0, int k0) {
        bool uniform = true;
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b)
                for (int c = 0; c < 3; ++c) {
                    m[a][b][c] = fine.at(i0 + a, j0 + b, k0 + c);
                    uniform = uniform && m[a][b][c] == m[0][0][0];
                }
        return !uniform;
    }
    std::int32_t at(const int (&q)[3]) const { return m[q[0]][q[1]][q[2]]; }

    // A coarse edge whose ends (0 and 2 along one axis, the others at 0 or
    // 2) agree changes material at its midpoint.
    bool edgeFails() const {
        for (int d = 0; d < 3; ++d)
            for (int u = 0; u <= 2; u += 2)
                for (int v = 0; v <= 2; v += 2) {
                    int p0[3], p1[3], pm[3];
                    const int e1 = (d + 1) % 3, e2 = (d + 2) % 3;
                    p0[d] = 0, p1[d] = 2, pm[d] = 1;
                    p0[e1] = p1[e1] = pm[e1] = u;
                    p0[e2] = p1[e2] = pm[e2] = v;
                    const auto a = at(p0), b = at(p1), c = at(pm);
                    if (a == b && c != a) return true;
                }
        return false;
    }

    // A coarse face (corners at 0/2 in two axes, fixed 0 or 2 in the third)
    // whose corners agree differs at its centre, or carries a diagonal pattern.
    bool faceFails() const {
        for (int d = 0; d < 3; ++d)
            for (int w = 0; w <= 2; w += 2) {
                const int e1 = (d + 1) % 3, e2 = (d + 2) % 3;
                std::int32_t corner[4];
                int n = 0;
                for (int u = 0; u <= 2; u += 2)
                    for (int v = 0; v <= 2; v += 2) {
                        int q[3];
                        q[d] = w, q[e1] = u, q[e2] = v;
                        corner[n++] = at(q);
                    }
                int q[3];
                q[d] = w, q[e1] = 1, q[e2] = 1;
                const auto centre = at(q);
                // corners in order (0,0) (0,2) (2,0) (2,2): diagonals are 0-3 and 1-2
                const bool allSame = corner[0] == corner[1] && corner[1] == corner[2] && corner[2] == corner[3];
                if (allSame && centre != corner[0]) return true;
                if (corner[0] == corner[3] && corner[1] == corner[2] && corner[0] != corner[1]) return true;
            }
        return false;
    }

    // All 8 corners agree but the centre differs, or a body-diagonal
    // pattern: two opposite corners share a material that no other corner
    // has, and they are not joined along a face.
    bool bodyFails() const {
        std::int32_t c8[8];
        for (int c = 0; c < 8; ++c) c8[c] = m[2 * (c & 1)][2 * (c >> 1 & 1)][2 * (c >> 2 & 1)];
        bool same = true;
        for (int c = 1; c < 8; ++c) same = same && c8[c] == c8[0];
        if (same && m[1][1][1] != c8[0]) return true;
        for (int c = 0; c < 8; ++c) {
            const int o = 7 - c;
            if (c8[c] != c8[o]) continue;
            bool alone = true;
            for (int e = 0; e < 8; ++e)
                if (e != c && e != o && c8[e] == c8[c]) alone = false;
            if (alone) return true;
        }
        return false;
    }
};

}  // namespace

std::size_t lbieFailures(const Labels& fine) {
    const auto [nx, ny, nz] = fine.grid.dims;
    std::atomic<std::size_t> failures{0};
    const int cx = (nx - 1) / 2, cy = (ny - 1) / 2, cz = (nz - 1) / 2;
    tbb::parallel_for(0, std::max(cz, 0), [&](int K) {
        std::size_t local = 0;
        CoarseCell cell;
        for (int J = 0; J < cy; ++J)
            for (int I = 0; I < cx; ++I)
                if (cell.read(fine, 2 * I, 2 * J, 2 * K))
                    local += cell.edgeFails() || cell.faceFails() || cell.bodyFails();
        failures += local;
    });
    return failures;
}

std::string LevelRejection::note() const {
    return "level " + std::to_string(level) + (cellTests ? ": " : " ") + why;
}

LevelChoice chooseLevel(const Domain& domain, const Grid& base, const LevelOptions& opt) {
    LevelChoice best;
    double refVolume = 0;
    for (int level = 0; level <= opt.maxLevel; ++level) {
        const Grid grid = coarsen(base, level);
        if (grid.dims[0] < 3 || grid.dims[1] < 3 || grid.dims[2] < 3) break;
        Labels labels = sampleLabels(domain, grid);
        repairNonManifold(labels, domain);
        const auto topo = regionTopology(labels);
        const double cellVolume = std::abs(grid.determinant());
        double volume = 0;
        for (const auto& t : topo) volume += static_cast<double>(t.points) * cellVolume;
        if (level == 0) {
            if (topo.empty()) throw Error("nothing to mesh: no grid point lies inside the selected material(s)");
            best.level = 0;
            best.grid = grid;
            best.topology = topo;
            best.reference = topo;
            refVolume = volume;
            continue;
        }
        const double change = refVolume > 0 ? std::abs(volume - refVolume) / refVolume : 0;
        bool sameTopology = topo.size() == best.reference.size();
        for (std::size_t i = 0; sameTopology && i < topo.size(); ++i)
            sameTopology = topo[i].material == best.reference[i].material &&
                           topo[i].components == best.reference[i].components &&
                           topo[i].euler == best.reference[i].euler;
        // LBIE: every coarse cell of this level must pass the topology tests on
        // the previous (finer) level's labels.
        if (opt.cellTests) {
            Labels finer = sampleLabels(domain, coarsen(base, level - 1));
            const std::size_t failing = lbieFailures(finer);
            if (failing > 0) {
                best.rejected = LevelRejection{
                    level, true, std::to_string(failing) + " coarse cells fail LBIE's sign-change and ambiguity tests"};
                break;
            }
        }
        bool enoughPoints = true;
        for (const auto& t : topo) enoughPoints = enoughPoints && t.points >= opt.minPoints;
        if (!sameTopology) {
            best.rejected = LevelRejection{level, false, "changes the topology (" + describe(topo) + ")"};
            break;
        }
        if (change > opt.maxVolumeChange) {
            char percent[64];
            std::snprintf(percent, sizeof percent, "%.1f%% (more than %.1f%%)", 100 * change, 100 * opt.maxVolumeChange);
            best.rejected = LevelRejection{level, false, std::string("changes the volume by ") + percent};
            break;
        }
        if (!enoughPoints) {
            best.rejected = LevelRejection{
                level, false, "leaves fewer than " + std::to_string(opt.minPoints) + " grid points in a material"};
            break;
        }
        best.level = level;
        best.grid = grid;
        best.topology = topo;
        best.volumeChange = change;
    }
    return best;
}

}  // namespace isohex::octree

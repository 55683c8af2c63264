#pragma once
// The polygoniser's surface in a window of the grid (private to octree/):
// the exact local test of whether changing a few grid points keeps the
// components and Euler characteristic of the surface a marching-cubes
// polygoniser draws around a material (see CellEdgeGroups). The repair's
// preferred flips and the topology matching both decide with it.
#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "isohex/octree/Labels.hpp"
#include "isohex/octree/TopologyMatch.hpp"

namespace isohex::octree {

// What mcLocal computes for one state of a window.
struct McLocal {
    long long chi = 0;
    int closed = 0;                        // pieces without a port
    std::vector<std::int32_t> portGroup;   // per vertex: first port of its piece (-1: not a port)
};

// The window of mcLocal around a box of changed points k[a] points wide on
// axis a: 4 more points on every side (a single point: 9x9x9). Relative to
// the box's lowest point (offset 0, window point 4), points at offsets -4..k+3.
struct McBox {
    std::array<int, 3> k{1, 1, 1};
    int w(int a) const { return k[a] + 8; }
    int points() const { return w(0) * w(1) * w(2); }
};

// in: the window's points (x fastest), true when inside. A change of the
// points in the box changes the raw patterns of the cells with a corner in it
// (offsets -1..k-1) and, through the ambiguous faces, the corrected patterns
// of the cells one further (-2..k): those are R. The faces that can change
// are the grid edges with both ends within -2..k+1.
void mcLocal(const std::vector<std::uint8_t>& in, const McBox& b, const CellEdgeGroups& t, McLocal& out);

using PointChange = std::pair<std::size_t, std::int32_t>;  // grid index, new material

// The window of box `b` whose box starts at grid point lo: 1 where the
// point has material m (points off the grid: 0).
void fillWindow(const Labels& l, const std::array<int, 3>& lo, const McBox& b, std::int32_t m,
                std::vector<std::uint8_t>& in);

// Whether giving the points of `changes` their new materials keeps the
// components and Euler characteristic of the polygoniser's surface of
// material m (m's points inside, every other point outside).
// (eulerChange: the change of the surface's Euler characteristic, exact.)
bool mcKeeps(const Labels& l, const std::vector<PointChange>& changes, std::int32_t m, const CellEdgeGroups& t,
             long long* eulerChange = nullptr);

// The polygon surface of material m in a fixed window (the box lo..hi of
// grid points that may change, and 4 points around it), compared with the
// window as it was when the probe was made: 0 when every change made since
// inside the box keeps the surface's components and Euler characteristic
// (as mcKeeps decides it), otherwise a count that grows with the difference
// (the Euler change, pieces without a port gained or lost, pieces joining
// or splitting ports). The deep search's measure.
class McProbe {
public:
    McProbe(const Labels& l, std::array<int, 3> lo, std::array<int, 3> hi, std::int32_t m, const CellEdgeGroups& t)
        : l_(l), lo_(lo), m_(m), t_(t) {
        for (int a = 0; a < 3; ++a) box_.k[a] = hi[a] - lo[a] + 1;
        fillWindow(l_, lo_, box_, m_, in_);
        mcLocal(in_, box_, t_, before_);
        beforeGroups_ = groups(before_);
    }
    long long distance() {
        fillWindow(l_, lo_, box_, m_, in_);
        mcLocal(in_, box_, t_, after_);
        long long d = std::abs(after_.chi - before_.chi) + std::abs(after_.closed - before_.closed);
        if (after_.portGroup != before_.portGroup) {
            const long long ga = groups(after_);
            d += ga == beforeGroups_ ? 1 : std::abs(ga - beforeGroups_);
        }
        return d;
    }

private:
    static long long groups(const McLocal& s) {
        long long n = 0;
        for (std::size_t v = 0; v < s.portGroup.size(); ++v) n += s.portGroup[v] == static_cast<std::int32_t>(v);
        return n;
    }
    const Labels& l_;
    std::array<int, 3> lo_;
    std::int32_t m_;
    const CellEdgeGroups& t_;
    McBox box_;
    std::vector<std::uint8_t> in_;
    McLocal before_, after_;
    long long beforeGroups_ = 0;
};

// mcKeeps for toggling material m at point (i, j, k).
bool mcKeeps(const Labels& l, int i, int j, int k, std::int32_t m, const CellEdgeGroups& t,
             long long* eulerChange = nullptr);

}  // namespace isohex::octree

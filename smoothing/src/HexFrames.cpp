#include "HexFrames.hpp"

#include <cstddef>
#include <cstdint>

#include "isohex/core/HexCell.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex::smoothing::detail {

using namespace vec;

namespace {

// The 9 frames (centre, corners 0..7) as signed node combinations: frame f,
// column j = sum over the hex's nodes of kFrame[f][j][n] * x[n].
struct FrameTable {
    std::array<std::array<std::array<double, 8>, 3>, 9> c{};
    FrameTable() {
        const int pos[3][4] = {{1, 2, 5, 6}, {2, 3, 6, 7}, {4, 5, 6, 7}};
        const int neg[3][4] = {{0, 3, 4, 7}, {0, 1, 4, 5}, {0, 1, 2, 3}};
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 4; ++i) {
                c[0][static_cast<std::size_t>(j)][static_cast<std::size_t>(pos[j][i])] = 1;
                c[0][static_cast<std::size_t>(j)][static_cast<std::size_t>(neg[j][i])] = -1;
            }
        for (int k = 0; k < 8; ++k)
            for (int j = 0; j < 3; ++j) {
                const auto sk = static_cast<std::size_t>(k), sj = static_cast<std::size_t>(j);
                c[sk + 1][sj][static_cast<std::size_t>(hexcell::kCornerNeighbours[sk][sj])] += 1;
                c[sk + 1][sj][sk] -= 1;
            }
    }
};

const FrameTable& frameTable() {
    static const FrameTable t;
    return t;
}

// The same table without its zeros: per frame and column, the nodes with a
// non-zero coefficient in increasing order (8 for the centre frame, 2 for a
// corner's). Sums taken over it add the same terms in the same order as a
// loop over all 8 nodes that skips the zeros, so the results are the same
// to the last bit; the joint release forms every frame of its region at
// every step, and the dense loop was a good part of its time.
struct SparseFrameTable {
    struct Term {
        std::uint8_t node;
        double coef;
    };
    std::array<std::array<std::array<Term, 8>, 3>, 9> terms{};
    std::array<std::array<std::uint8_t, 3>, 9> count{};
    SparseFrameTable() {
        const FrameTable& t = frameTable();
        for (std::size_t f = 0; f < 9; ++f)
            for (std::size_t j = 0; j < 3; ++j)
                for (std::size_t n = 0; n < 8; ++n)
                    if (t.c[f][j][n] != 0) terms[f][j][count[f][j]++] = {static_cast<std::uint8_t>(n), t.c[f][j][n]};
    }
};

const SparseFrameTable& sparseFrameTable() {
    static const SparseFrameTable t;
    return t;
}

}  // namespace

void frameValues(const HexCoords& x, HexFrames& out, double scale) {
    const SparseFrameTable& t = sparseFrameTable();
    for (std::size_t f = 0; f < 9; ++f) {
        FrameState& st = out[f];
        for (std::size_t j = 0; j < 3; ++j) {
            Vec3 v{0, 0, 0};
            for (std::size_t i = 0; i < t.count[f][j]; ++i) v = v + t.terms[f][j][i].coef * x[t.terms[f][j][i].node];
            st.col[j] = v;
        }
        st.cross = {cross(st.col[1], st.col[2]), cross(st.col[2], st.col[0]), cross(st.col[0], st.col[1])};
        if (scale > 0) {
            st.collapsed = false;
            st.s = dot(st.col[0], st.cross[0]) * (f == 0 ? scale / 64 : scale);
            continue;
        }
        st.la = norm(st.col[0]), st.lb = norm(st.col[1]), st.lc = norm(st.col[2]);
        st.len = st.la * st.lb * st.lc;
        st.collapsed = !(st.len > 1e-300);
        if (st.collapsed) {  // as bad as it gets, no direction
            st.s = -2;
            continue;
        }
        st.s = dot(st.col[0], st.cross[0]) / st.len;
    }
}

void frameGradients(const HexFrames& frames, const double* weight, std::array<Vec3, 8>& grad, double scale) {
    const SparseFrameTable& t = sparseFrameTable();
    for (std::size_t f = 0; f < 9; ++f) {
        const FrameState& st = frames[f];
        if (st.collapsed || weight[f] == 0) continue;
        std::array<Vec3, 3> g;
        if (scale > 0) {
            const double k = f == 0 ? scale / 64 : scale;  // d det / d column j = cross[j]
            g = {k * st.cross[0], k * st.cross[1], k * st.cross[2]};
        } else {
            g = {(1.0 / st.len) * st.cross[0] - (st.s / (st.la * st.la)) * st.col[0],
                 (1.0 / st.len) * st.cross[1] - (st.s / (st.lb * st.lb)) * st.col[1],
                 (1.0 / st.len) * st.cross[2] - (st.s / (st.lc * st.lc)) * st.col[2]};
        }
        for (std::size_t j = 0; j < 3; ++j)
            for (std::size_t i = 0; i < t.count[f][j]; ++i) {
                const auto& term = t.terms[f][j][i];
                grad[term.node] = grad[term.node] + (weight[f] * term.coef) * g[j];
            }
    }
}


}  // namespace isohex::smoothing::detail

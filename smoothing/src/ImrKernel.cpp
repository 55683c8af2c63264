// Four corner terms at a time; see ImrKernel.hpp. Every expression below
// repeats, lane by lane, the operations of normDet, frameDeterminant,
// roleTimes and InverseMeanRatio in CornerMetrics.hpp in their order,
// including the orders Eigen sums in for these fixed sizes (a 3x3 matrix's
// squared norm: (e0^2 + e2^2) + (e4^2 + e6^2), then the odd entries, then
// e8^2; a matrix times a vector: rows x and y left to right, row z as
// (a_z1 w1 + a_z2 w2) + a_z0 w0). If one of those changes, the bitwise test
// in test_metrics.cpp fails.
#include "isohex/smoothing/ImrKernel.hpp"

// The lane type is 32 bytes wide; its helpers are always inlined, so no
// function passes one across the baseline ABI (where GCC would warn).
#pragma GCC diagnostic ignored "-Wpsabi"

#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>

#include "isohex/smoothing/NodeObjective.hpp"

namespace isohex::smoothing::detail {
namespace {

typedef double Lanes __attribute__((vector_size(32)));
typedef long long Mask __attribute__((vector_size(32)));
constexpr int kLanes = 4;
constexpr double kInf = std::numeric_limits<double>::infinity();

#define ISOHEX_LANES inline __attribute__((always_inline))

constexpr std::size_t kMaxBlocks = (ImrState::kCapacity + kLanes - 1) / kLanes;

// inverseCubeRoot, lane by lane, of `blocks` blocks of lanes at once. Each
// Newton step is a chain of six dependent multiplications; taking step k of
// every block before step k + 1 of any lets the blocks' chains overlap
// (block by block, the cube roots were most of a value()).
ISOHEX_LANES void inverseCubeRoots(const Lanes* t, Lanes* y, std::size_t blocks) {
    for (std::size_t b = 0; b < blocks; ++b) {
        Mask bits;
        std::memcpy(&bits, &t[b], sizeof bits);
        bits = 0x553ef0ff289dd796LL - bits / 3;
        std::memcpy(&y[b], &bits, sizeof y[b]);
    }
    for (int k = 0; k < 4; ++k)
        for (std::size_t b = 0; b < blocks; ++b) y[b] = y[b] * (4.0 - t[b] * y[b] * y[b] * y[b]) * (1.0 / 3.0);
    const Lanes lo = {1e-18, 1e-18, 1e-18, 1e-18}, hi = {1e18, 1e18, 1e18, 1e18};
    for (std::size_t b = 0; b < blocks; ++b) {
        const Mask inRange = (t[b] > lo) & (t[b] < hi);
        if (inRange[0] && inRange[1] && inRange[2] && inRange[3]) continue;
        for (int k = 0; k < kLanes; ++k)
            if (!inRange[k]) y[b][k] = 1.0 / std::cbrt(t[b][k]);
    }
}

constexpr int kRow[6] = {0, 0, 0, 1, 1, 2}, kCol[6] = {0, 1, 2, 1, 2, 2};  // Hessian entries xx xy xz yy yz zz

// The frames of terms i .. i+3 in lanes (lanes past `count` repeat the last
// term; their results are never read) and the role of each lane.
struct Frames {
    Lanes e[9];  // column-major: column j is e[3j .. 3j+2]
    Mask role;
    Lanes cw[3];  // the centre frame's weights (0 for other roles)
};
ISOHEX_LANES void loadFrames(const CornerTerm* terms, std::size_t count, std::size_t i, Frames& f) {
    for (int k = 0; k < kLanes; ++k) {
        const CornerTerm& term = terms[std::min(i + static_cast<std::size_t>(k), count - 1)];
        const double* a = term.A.data();
        for (int j = 0; j < 9; ++j) f.e[j][k] = a[j];
        f.role[k] = term.role;
        const Vector3 w = term.role >= kCentreRole ? centreWeights(term.role) : Vector3::Zero();
        for (int j = 0; j < 3; ++j) f.cw[j][k] = w[j];
    }
}

ISOHEX_LANES void cross(const Lanes* a, const Lanes* b, Lanes* r) {
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}
ISOHEX_LANES Lanes dot(const Lanes* a, const Lanes* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
// Matrix3::squaredNorm in Eigen's order.
ISOHEX_LANES Lanes squaredNorm(const Lanes* e) {
    return ((e[0] * e[0] + e[2] * e[2]) + (e[4] * e[4] + e[6] * e[6])) +
           ((e[1] * e[1] + e[3] * e[3]) + (e[5] * e[5] + e[7] * e[7])) + e[8] * e[8];
}

// normDet of terms i .. i+3 into the state.
ISOHEX_LANES void normDetBlock(const CornerTerm* terms, std::size_t count, std::size_t i, ImrState& s) {
    Frames f;
    loadFrames(terms, count, i, f);
    const Lanes* c0 = f.e;
    const Lanes* c1 = f.e + 3;
    const Lanes* c2 = f.e + 6;
    Lanes X[3], Y[3], Z[3];
    cross(c1, c2, X);  // role 0's gradient, and bc of the corner and centre roles
    cross(c2, c0, Y);  // role 1's
    cross(c0, c1, Z);  // role 2's
    const Mask r0 = f.role == 0, r1 = f.role == 1, r2 = f.role == 2, r3 = f.role == kCornerRole;
    const Lanes t = r1 ? dot(c1, Y) : (r2 ? dot(c2, Z) : dot(c0, X));
    std::memcpy(s.t + i, &t, sizeof t);
    for (int c = 0; c < 3; ++c) {
        const Lanes corner = -(X[c] + Y[c] + Z[c]);
        const Lanes centre = f.cw[0] * X[c] + f.cw[1] * Y[c] + f.cw[2] * Z[c];
        const Lanes gt = r0 ? X[c] : (r1 ? Y[c] : (r2 ? Z[c] : (r3 ? corner : centre)));
        std::memcpy(s.gt[c] + i, &gt, sizeof gt);
    }
    // 2 A w: a column, minus the sum of the columns, or A times the centre
    // weights (rows x and y left to right, row z as Eigen sums it)
    for (int c = 0; c < 3; ++c) {
        const Lanes aw = c < 2 ? f.cw[0] * c0[c] + f.cw[1] * c1[c] + f.cw[2] * c2[c]
                               : f.cw[1] * c1[c] + f.cw[2] * c2[c] + f.cw[0] * c0[c];
        const Lanes corner = -(c0[c] + c1[c] + c2[c]);
        const Lanes gn = 2.0 * (r0 ? c0[c] : (r1 ? c1[c] : (r2 ? c2[c] : (r3 ? corner : aw))));
        std::memcpy(s.gn[c] + i, &gn, sizeof gn);
    }
    const Lanes n = squaredNorm(f.e);
    std::memcpy(s.n + i, &n, sizeof n);
    const Lanes one = {1.0, 1.0, 1.0, 1.0}, three = {3.0, 3.0, 3.0, 3.0};
    const Lanes centreNorm = {3.0 / 16, 3.0 / 16, 3.0 / 16, 3.0 / 16};
    const Lanes w2 = (f.role < kCornerRole) ? one : (r3 ? three : centreNorm);
    std::memcpy(s.w2 + i, &w2, sizeof w2);
}

// The state of terms i .. i+3 into lanes.
ISOHEX_LANES void loadState(const ImrState& s, std::size_t i, Lanes& n, Lanes& t, Lanes& w2, Lanes* gn, Lanes* gt) {
    std::memcpy(&n, s.n + i, sizeof n);
    std::memcpy(&t, s.t + i, sizeof t);
    std::memcpy(&w2, s.w2 + i, sizeof w2);
    for (int c = 0; c < 3; ++c) {
        std::memcpy(&gn[c], s.gn[c] + i, sizeof n);
        std::memcpy(&gt[c], s.gt[c] + i, sizeof n);
    }
}

ISOHEX_LANES double derivativesBody(const CornerTerm* terms, std::size_t count, ImrState& s, Vector3& g, Matrix3& H) {
    g.setZero();
    H.setZero();
    // First every term's n, t and gradients; an infeasible term ends it there
    // (the scalar loop returns at the first one too).
    for (std::size_t i = 0; i < count; i += kLanes) normDetBlock(terms, count, i, s);
    for (std::size_t i = 0; i < count; ++i)
        if (!(s.t[i] > 0)) return kInf;
    // Then InverseMeanRatio::derivativesFromState; the blocks do not depend
    // on each other until the sums, so their cube roots overlap.
    double sum = 0;
    double gs[3] = {0, 0, 0}, hs[6] = {0, 0, 0, 0, 0, 0};
    const std::size_t blocks = (count + kLanes - 1) / kLanes;
    Lanes ts[kMaxBlocks], ys[kMaxBlocks];
    std::memcpy(ts, s.t, blocks * sizeof(Lanes));
    inverseCubeRoots(ts, ys, blocks);
    for (std::size_t i = 0; i < count; i += kLanes) {
        Lanes n, t, w2, gn[3], gt[3];
        loadState(s, i, n, t, w2, gn, gt);
        const Lanes y = ys[i / kLanes];
        const Lanes sc = y * y * (1.0 / 3.0);
        const Lanes invT = y * y * y;
        const Lanes value = n * sc;
        const Lanes k = (2.0 / 3.0) * n * invT;
        Lanes grad[3], hess[6];
        for (int c = 0; c < 3; ++c) grad[c] = sc * (gn[c] - k * gt[c]);
        const Lanes a = (2.0 / 3.0) * invT, b = (10.0 / 9.0) * n * invT * invT;
        for (int h = 0; h < 6; ++h) {
            const int p = kRow[h], q = kCol[h];
            const Lanes diagonal = p == q ? 2.0 * w2 : Lanes{0.0, 0.0, 0.0, 0.0};
            hess[h] = sc * (b * gt[p] * gt[q] - a * (gn[p] * gt[q] + gt[p] * gn[q]) + diagonal);
        }
        const std::size_t lanes = std::min<std::size_t>(kLanes, count - i);
        for (std::size_t l = 0; l < lanes; ++l) {
            sum += value[l];
            for (int c = 0; c < 3; ++c) gs[c] += grad[c][l];
            for (int h = 0; h < 6; ++h) hs[h] += hess[h][l];
        }
    }
    g = Vector3(gs[0], gs[1], gs[2]);
    for (int h = 0; h < 6; ++h) H(kRow[h], kCol[h]) = H(kCol[h], kRow[h]) = hs[h];
    return sum;
}

// InverseMeanRatio::fromNormDet of `count` terms (at most kCapacity), from
// their n and t in blocks of lanes, added to sum in term order; false (sum
// meaningless) at a term with t <= 0, the barrier.
ISOHEX_LANES bool addValues(const Lanes* n, const Lanes* t, std::size_t count, double& sum) {
    const std::size_t blocks = (count + kLanes - 1) / kLanes;
    Lanes y[kMaxBlocks];
    inverseCubeRoots(t, y, blocks);
    for (std::size_t b = 0; b < blocks; ++b) {
        const Lanes v = n[b] * (y[b] * y[b]) * (1.0 / 3.0);
        const std::size_t lanes = std::min<std::size_t>(kLanes, count - b * kLanes);
        for (std::size_t k = 0; k < lanes; ++k) {
            if (!(t[b][k] > 0)) return false;
            sum += v[k];
        }
    }
    return true;
}

ISOHEX_LANES double valueBody(const ImrState& s, std::size_t count, const Vector3& d) {
    const double d0 = d[0], d1 = d[1], d2 = d[2];
    const double dd = d0 * d0 + d1 * d1 + d2 * d2;
    Lanes nn[kMaxBlocks], tt[kMaxBlocks];
    for (std::size_t i = 0; i < count; i += kLanes) {
        Lanes n, t, w2, gn[3], gt[3];
        loadState(s, i, n, t, w2, gn, gt);
        // (lanes past `count` hold stale numbers and are not read below)
        nn[i / kLanes] = n + (gn[0] * d0 + gn[1] * d1 + gn[2] * d2) + w2 * dd;
        tt[i / kLanes] = t + (gt[0] * d0 + gt[1] * d1 + gt[2] * d2);
    }
    double sum = 0;
    return addValues(nn, tt, count, sum) ? sum : kInf;
}

// n and t of the frames of terms c0 .. c1-1 (blocks of lanes from c0, a
// multiple of four) displaced by d: displaceFrame, then the squared norm and
// cornerDeterminant of the moved frame.
ISOHEX_LANES void displacedNormDets(const CornerTerm* terms, std::size_t count, std::size_t c0, std::size_t c1,
                                    const Lanes* dv, Lanes* ns, Lanes* ts) {
    for (std::size_t i = c0; i < c1; i += kLanes) {
        Frames f;
        loadFrames(terms, count, i, f);
        for (int j = 0; j < 3; ++j) {
            const Mask own = f.role == j;  // the node is column j: the column moves by d
            const Mask corner = f.role == kCornerRole;  // every column moves by -d
            const Mask centre = f.role >= kCentreRole;  // column j moves by d w_j
            for (int c = 0; c < 3; ++c) {
                Lanes& x = f.e[3 * j + c];
                x = own ? x + dv[c] : (corner ? x - dv[c] : (centre ? x + dv[c] * f.cw[j] : x));
            }
        }
        Lanes X[3];
        cross(f.e + 3, f.e + 6, X);
        ts[(i - c0) / kLanes] = dot(f.e, X);
        ns[(i - c0) / kLanes] = squaredNorm(f.e);
    }
}

// InverseMeanRatio::value of each frame displaced by d, summed in order; any
// number of terms, in chunks of what the lanes hold.
ISOHEX_LANES double frameValueBody(const CornerTerm* terms, std::size_t count, const Vector3& d) {
    const Lanes dv[3] = {{d[0], d[0], d[0], d[0]}, {d[1], d[1], d[1], d[1]}, {d[2], d[2], d[2], d[2]}};
    Lanes ns[kMaxBlocks], ts[kMaxBlocks];
    double sum = 0;
    for (std::size_t c0 = 0; c0 < count; c0 += ImrState::kCapacity) {
        const std::size_t c1 = std::min(count, c0 + ImrState::kCapacity);
        displacedNormDets(terms, count, c0, c1, dv, ns, ts);
        if (!addValues(ns, ts, c1 - c0, sum)) return kInf;
    }
    return sum;
}

double derivativesBaseline(const CornerTerm* terms, std::size_t count, ImrState& s, Vector3& g, Matrix3& H) {
    return derivativesBody(terms, count, s, g, H);
}
double valueBaseline(const ImrState& s, std::size_t count, const Vector3& d) { return valueBody(s, count, d); }
double frameValueBaseline(const CornerTerm* terms, std::size_t count, const Vector3& d) {
    return frameValueBody(terms, count, d);
}

__attribute__((target("avx2"))) double derivativesAvx2(const CornerTerm* terms, std::size_t count, ImrState& s,
                                                       Vector3& g, Matrix3& H) {
    return derivativesBody(terms, count, s, g, H);
}
__attribute__((target("avx2"))) double valueAvx2(const ImrState& s, std::size_t count, const Vector3& d) {
    return valueBody(s, count, d);
}
__attribute__((target("avx2"))) double frameValueAvx2(const CornerTerm* terms, std::size_t count, const Vector3& d) {
    return frameValueBody(terms, count, d);
}

bool processorHasAvx2() {
    static const bool has = [] {
        __builtin_cpu_init();
        return __builtin_cpu_supports("avx2") != 0;
    }();
    return has;
}

std::atomic<bool> avx2Allowed{true};

bool avx2() { return avx2Allowed.load(std::memory_order_relaxed) && processorHasAvx2(); }

}  // namespace

double imrDerivatives(const CornerTerm* terms, std::size_t count, ImrState& state, Vector3& g, Matrix3& H) {
    if (count == 0) {
        g.setZero();
        H.setZero();
        return 0.0;
    }
    return avx2() ? derivativesAvx2(terms, count, state, g, H) : derivativesBaseline(terms, count, state, g, H);
}

double imrValue(const ImrState& state, std::size_t count, const Vector3& d) {
    return avx2() ? valueAvx2(state, count, d) : valueBaseline(state, count, d);
}

double imrFrameValue(const CornerTerm* terms, std::size_t count, const Vector3& d) {
    if (count == 0) return 0.0;
    return avx2() ? frameValueAvx2(terms, count, d) : frameValueBaseline(terms, count, d);
}

const char* imrInstructionSet() { return avx2() ? "avx2" : "sse2"; }

void useAvx2(bool enable) { avx2Allowed.store(enable, std::memory_order_relaxed); }

}  // namespace isohex::smoothing::detail

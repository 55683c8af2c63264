#include "isohex/core/Quality.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"

namespace isohex {

namespace {

// Verdict's thresholds: a squared length at or below kTiny counts as zero and
// the metric returns kHuge.
constexpr double kTiny = 1e-30;
constexpr double kHuge = 1e30;

inline Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// The 9 Jacobian columns Verdict uses: index 0 = the centre principal axes,
// 1..8 = corners 0..7.
struct NineFrames {
    std::array<std::array<Vec3, 3>, 9> v;
};

NineFrames frames(const HexCoords& x) {
    NineFrames f;
    f.v[0] = centreAxes(x);
    for (int k = 0; k < 8; ++k)
        for (int j = 0; j < 3; ++j) f.v[k + 1][j] = sub(x[hexcell::kCornerNeighbours[k][j]], x[k]);
    return f;
}

}  // namespace

double scaledJacobian(const HexCoords& x) {
    const NineFrames f = frames(x);
    double best = kScaledJacobianCollapsed;
    for (const auto& [a, b, c] : f.v) {
        const double s = frameScaledJacobian(a, b, c);
        if (s == kScaledJacobianCollapsed) return s;
        best = std::min(best, s);
    }
    return clampScaledJacobian(best);
}

double inverseMeanRatio(const HexCoords& x) {
    double sum = 0;
    for (int k = 0; k < 8; ++k) {
        const auto& n = hexcell::kCornerNeighbours[k];
        const Vec3 a = sub(x[n[0]], x[k]), b = sub(x[n[1]], x[k]), c = sub(x[n[2]], x[k]);
        const double det = dot(a, cross(b, c));
        if (!(det > 0)) return std::numeric_limits<double>::infinity();
        sum += (dot(a, a) + dot(b, b) + dot(c, c)) / (3.0 * std::cbrt(det * det));
    }
    return sum / 8.0;
}

double conditionNumber(const HexCoords& x) {
    const NineFrames f = frames(x);
    double worst = 0;
    for (const auto& [a, b, c] : f.v) {
        const double det = dot(a, cross(b, c));
        if (det <= kTiny) {
            worst = kHuge;
            break;
        }
        const Vec3 ab = cross(a, b), bc = cross(b, c), ca = cross(c, a);
        const double fro2 = dot(a, a) + dot(b, b) + dot(c, c);
        const double adj2 = dot(ab, ab) + dot(bc, bc) + dot(ca, ca);
        worst = std::max(worst, std::sqrt(fro2 * adj2) / det);
    }
    const double cond = worst / 3.0;
    return std::min(cond, kHuge);
}

double edgeRatio(const HexCoords& x) {
    double lo = std::numeric_limits<double>::infinity(), hi = 0;
    for (const auto& e : hexcell::kEdges) {
        const Vec3 d = sub(x[e[1]], x[e[0]]);
        const double l2 = dot(d, d);
        lo = std::min(lo, l2);
        hi = std::max(hi, l2);
    }
    if (lo < kTiny) return kHuge;
    return std::min(std::sqrt(hi / lo), kHuge);
}

double hexVolume(const HexCoords& x) {
    // The trilinear map in monomial form, x(u,v,w) = x0 + b u + c v + d w +
    // e uv + f uw + g vw + h uvw (VTK corner order), so each Jacobian column is
    // a few multiply-adds; det J has degree at most 2 in each parameter, so the
    // 2x2x2 Gauss rule on [0,1]^3 integrates it exactly.
    Vec3 b, c, d, e, f, g, h;
    for (int k = 0; k < 3; ++k) {
        b[k] = x[1][k] - x[0][k];
        c[k] = x[3][k] - x[0][k];
        d[k] = x[4][k] - x[0][k];
        e[k] = x[2][k] - x[1][k] - x[3][k] + x[0][k];
        f[k] = x[5][k] - x[1][k] - x[4][k] + x[0][k];
        g[k] = x[7][k] - x[3][k] - x[4][k] + x[0][k];
        h[k] = x[6][k] - x[2][k] - x[5][k] - x[7][k] + x[1][k] + x[3][k] + x[4][k] - x[0][k];
    }
    constexpr double lo = 0.21132486540518713, hi = 0.78867513459481287;  // 1/2 -+ 1/(2 sqrt 3)
    constexpr double gp[2] = {lo, hi};
    double vol = 0;
    for (double u : gp)
        for (double v : gp)
            for (double w : gp) {
                Vec3 ju, jv, jw;
                for (int k = 0; k < 3; ++k) {
                    ju[k] = b[k] + e[k] * v + f[k] * w + h[k] * v * w;
                    jv[k] = c[k] + e[k] * u + g[k] * w + h[k] * u * w;
                    jw[k] = d[k] + f[k] * u + g[k] * v + h[k] * u * v;
                }
                vol += dot(ju, cross(jv, jw));
            }
    return vol / 8.0;
}

double minCornerDeterminant(const HexCoords& x) {
    double m = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 8; ++k) {
        const auto& n = hexcell::kCornerNeighbours[k];
        m = std::min(m, dot(sub(x[n[0]], x[k]), cross(sub(x[n[1]], x[k]), sub(x[n[2]], x[k]))));
    }
    return m;
}

double centreDeterminant(const HexCoords& x) {
    // frames() gives the centre axes as sums of four edges: scale back to means.
    const NineFrames f = frames(x);
    return dot(f.v[0][0], cross(f.v[0][1], f.v[0][2])) / 64.0;
}

double minJacobianDeterminant(const HexCoords& x) {
    const NineFrames f = frames(x);
    double m = dot(f.v[0][0], cross(f.v[0][1], f.v[0][2])) / 64.0;
    for (int k = 1; k < 9; ++k) m = std::min(m, dot(f.v[k][0], cross(f.v[k][1], f.v[k][2])));
    return m;
}

HexCoords hexCoords(const HexMesh& mesh, Index hex) {
    HexCoords x;
    const Hex& h = mesh.hexes[static_cast<std::size_t>(hex)];
    for (int i = 0; i < 8; ++i) x[i] = mesh.nodes[static_cast<std::size_t>(h[i])];
    return x;
}

Vec3 hexCentre(const HexMesh& mesh, Index hex) {
    Vec3 c{0, 0, 0};
    for (const Vec3& x : hexCoords(mesh, hex))
        for (int i = 0; i < 3; ++i) c[i] += x[i] / 8.0;
    return c;
}

HexQuality computeQuality(const HexMesh& mesh) {
    const std::size_t H = mesh.hexes.size();
    HexQuality q;
    q.scaledJacobian.resize(H);
    q.inverseMeanRatio.resize(H);
    q.condition.resize(H);
    q.edgeRatio.resize(H);
    q.volume.resize(H);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, H, 2048), [&](const auto& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h) {
            const HexCoords x = hexCoords(mesh, static_cast<Index>(h));
            q.scaledJacobian[h] = scaledJacobian(x);
            q.inverseMeanRatio[h] = inverseMeanRatio(x);
            q.condition[h] = conditionNumber(x);
            q.edgeRatio[h] = edgeRatio(x);
            q.volume[h] = hexVolume(x);
        }
    });
    return q;
}

std::vector<double> scaledJacobians(const HexMesh& mesh) {
    std::vector<double> sj(mesh.hexes.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, sj.size(), 4096), [&](const auto& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h) sj[h] = scaledJacobian(hexCoords(mesh, static_cast<Index>(h)));
    });
    return sj;
}

namespace {

struct Acc {
    double min = std::numeric_limits<double>::infinity();
    double max = -std::numeric_limits<double>::infinity();
    double sum = 0;
    std::size_t n = 0;
    void add(double v) {
        min = std::min(min, v);
        max = std::max(max, v);
        sum += v;
        ++n;
    }
    void join(const Acc& o) {
        min = std::min(min, o.min);
        max = std::max(max, o.max);
        sum += o.sum;
        n += o.n;
    }
    Stats stats() const { return n ? Stats{min, sum / static_cast<double>(n), max, n} : Stats{}; }
};

struct SummaryAcc {
    Acc sj, imr, cond, er, vol;
    std::size_t inverted = 0, below = 0, degenerate = 0;
    std::array<std::size_t, 11> hist{};
    void join(const SummaryAcc& o) {
        sj.join(o.sj);
        imr.join(o.imr);
        cond.join(o.cond);
        er.join(o.er);
        vol.join(o.vol);
        inverted += o.inverted;
        below += o.below;
        degenerate += o.degenerate;
        for (std::size_t i = 0; i < hist.size(); ++i) hist[i] += o.hist[i];
    }
};

}  // namespace

QualitySummary summarize(const HexMesh& mesh, const HexQuality& q) {
    const std::size_t H = q.scaledJacobian.size();
    // Fixed blocks combined in order: sums do not depend on the thread count.
    const SummaryAcc acc = tbb::parallel_deterministic_reduce(
        tbb::blocked_range<std::size_t>(0, H, 4096), SummaryAcc{},
        [&](const tbb::blocked_range<std::size_t>& r, SummaryAcc a) {
            for (std::size_t h = r.begin(); h != r.end(); ++h) {
                const double sj = q.scaledJacobian[h];
                if (scaledJacobianCollapsed(sj)) {
                    ++a.degenerate;
                    ++a.below;
                } else {
                    a.sj.add(sj);
                    if (sj < 0) ++a.inverted;
                    if (sj < kPoorScaledJacobian) ++a.below;
                    const auto* it = std::upper_bound(kScaledJacobianBins.begin(), kScaledJacobianBins.end(), sj);
                    const long bin = std::clamp<long>(it - kScaledJacobianBins.begin() - 1, 0, 10);
                    ++a.hist[static_cast<std::size_t>(bin)];
                }
                if (std::isfinite(q.inverseMeanRatio[h])) a.imr.add(q.inverseMeanRatio[h]);
                a.cond.add(q.condition[h]);
                a.er.add(q.edgeRatio[h]);
                a.vol.add(q.volume[h]);
            }
            return a;
        },
        [](SummaryAcc a, const SummaryAcc& b) {
            a.join(b);
            return a;
        });
    QualitySummary s;
    s.hexes = mesh.hexes.size();
    s.nodes = mesh.nodes.size();
    s.scaledJacobian = acc.sj.stats();
    s.inverted = acc.inverted;
    s.below02 = acc.below;
    s.degenerate = acc.degenerate;
    s.histogram = acc.hist;
    s.inverseMeanRatio = acc.imr.stats();
    s.condition = acc.cond.stats();
    s.edgeRatio = acc.er.stats();
    s.volume = acc.vol.stats();
    s.totalVolume = acc.vol.sum;
    return s;
}

namespace {
nlohmann::json statsJson(const Stats& s) {
    if (s.count == 0) return {{"min", nullptr}, {"mean", nullptr}, {"max", nullptr}};
    return {{"min", s.min}, {"mean", s.mean}, {"max", s.max}};
}
}  // namespace

nlohmann::json toJson(const QualitySummary& s) {
    nlohmann::json sj = statsJson(s.scaledJacobian);
    sj["below_0_2"] = s.below02;
    sj["inverted"] = s.inverted;
    sj["degenerate"] = s.degenerate;
    sj["histogram"] = {{"edges", kScaledJacobianBins}, {"counts", s.histogram}};
    nlohmann::json imr = statsJson(s.inverseMeanRatio);
    imr["infinite"] = s.hexes - s.inverseMeanRatio.count;
    nlohmann::json vol = statsJson(s.volume);
    vol["total"] = s.totalVolume;
    return {{"hexes", s.hexes},
            {"nodes", s.nodes},
            {"scaled_jacobian", sj},
            {"inverse_mean_ratio", imr},
            {"condition", statsJson(s.condition)},
            {"edge_ratio", statsJson(s.edgeRatio)},
            {"volume", vol}};
}

void refuseMirroredCornerOrder(const std::string& path, std::size_t inverted, std::size_t hexes,
                               const std::string& consequence) {
    if (2 * inverted <= hexes) return;
    throw Error(path + ": " + std::to_string(inverted) + " of " + std::to_string(hexes) +
                " hexes are inverted, so the corner order is probably mirrored: isohex reads VTK's hexahedron "
                "order (bottom face counter-clockwise seen from the top face, then the top face). Reorder the "
                "corners and retry; " + consequence);
}

}  // namespace isohex

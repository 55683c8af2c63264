#pragma once
// Element quality, with Verdict's definitions so numbers agree with VTK,
// ParaView and CUBIT.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "isohex/core/HexMesh.hpp"

namespace isohex {

using HexCoords = std::array<Vec3, 8>;

// Verdict's HexScaledJacobian: the minimum of a.(b x c)/(|a||b||c|) over the
// 8 corners (edge vectors along kCornerNeighbours) and the centre principal
// axes. Returns 1e30, like Verdict, when any of those vectors has squared
// length <= 1e-30 (a collapsed hex): scaledJacobianCollapsed tells it apart.
double scaledJacobian(const HexCoords& x);

// Whether a scaledJacobian value marks a collapsed (degenerate) hex. A valid
// value is at most 1, but a perfect cube can give 1 plus a rounding error
// (on meshes of a few centimetres in metres), hence the tolerance: with a
// plain `> 1` such cubes were counted as degenerate.
inline bool scaledJacobianCollapsed(double sj) { return sj > 1.0 + 1e-9; }

// The pieces of scaledJacobian, for callers that evaluate a hex again and
// again with one node moved (the worst-hex pass keeps the frames the node is
// not part of): one frame's a.(b x c)/(|a||b||c|), or kScaledJacobianCollapsed
// when a vector has squared length <= 1e-30; the centre principal axes (sums
// of four edges each); and the clamp applied to the minimum over the frames.
inline constexpr double kScaledJacobianCollapsed = 1e30;
inline double frameScaledJacobian(const Vec3& a, const Vec3& b, const Vec3& c) {
    const double la = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
    const double lb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
    const double lc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    if (la <= 1e-30 || lb <= 1e-30 || lc <= 1e-30) return kScaledJacobianCollapsed;
    const Vec3 bc{b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2], b[0] * c[1] - b[1] * c[0]};
    return (a[0] * bc[0] + a[1] * bc[1] + a[2] * bc[2]) / std::sqrt(la * lb * lc);
}
inline std::array<Vec3, 3> centreAxes(const HexCoords& x) {
    std::array<Vec3, 3> v;
    for (int c = 0; c < 3; ++c) {
        v[0][c] = (x[1][c] + x[2][c] + x[5][c] + x[6][c]) - (x[0][c] + x[3][c] + x[4][c] + x[7][c]);
        v[1][c] = (x[2][c] + x[3][c] + x[6][c] + x[7][c]) - (x[0][c] + x[1][c] + x[4][c] + x[5][c]);
        v[2][c] = (x[4][c] + x[5][c] + x[6][c] + x[7][c]) - (x[0][c] + x[1][c] + x[2][c] + x[3][c]);
    }
    return v;
}
inline double clampScaledJacobian(double best) {
    return best > 0 ? std::min(best, kScaledJacobianCollapsed) : std::max(best, -kScaledJacobianCollapsed);
}
// Knupp's inverse mean ratio averaged over the 8 corners: |A|_F^2 / (3 det(A)^(2/3))
// per corner with A = [x_a - x_k, x_b - x_k, x_c - x_k]; 1 for a cube,
// +infinity if any corner determinant is <= 0.
double inverseMeanRatio(const HexCoords& x);
// Verdict's HexCondition: max over the 9 Jacobians of |A|_F |A^-1|_F, divided by 3.
double conditionNumber(const HexCoords& x);
// Edge ratio as Verdict documents it: longest / shortest of the 12 edges (1e30 when an edge
// vanishes). VTK 9.1's vtkMeshQuality returns other values for distorted hexes.
double edgeRatio(const HexCoords& x);
// Exact volume of the trilinear hex (2x2x2 Gauss quadrature of det J is exact).
double hexVolume(const HexCoords& x);
// Smallest corner Jacobian determinant (unscaled).
double minCornerDeterminant(const HexCoords& x);
// Determinant of the Jacobian at the centre: columns are the mean of the four
// edges along each reference axis (same scale as a corner determinant).
double centreDeterminant(const HexCoords& x);
// The inversion test of validate() and Verdict: the smallest of the 8 corner
// determinants and the centre one.
double minJacobianDeterminant(const HexCoords& x);

HexCoords hexCoords(const HexMesh& mesh, Index hex);
// The mean of a hex's eight corners.
Vec3 hexCentre(const HexMesh& mesh, Index hex);

struct HexQuality {
    std::vector<double> scaledJacobian;
    std::vector<double> inverseMeanRatio;
    std::vector<double> condition;
    std::vector<double> edgeRatio;
    std::vector<double> volume;
};
HexQuality computeQuality(const HexMesh& mesh);      // parallel over hexes
std::vector<double> scaledJacobians(const HexMesh& mesh);

// Fixed histogram edges so runs can be compared: [-1,0), [0,0.1), ..., [0.9,1.0].
inline constexpr std::array<double, 12> kScaledJacobianBins = {-1.0, 0.0, 0.1, 0.2, 0.3, 0.4,
                                                               0.5, 0.6, 0.7, 0.8, 0.9, 1.0};
// "questionable or unacceptable" in the seed
inline constexpr double kPoorScaledJacobian = 0.2;

struct Stats {
    double min = 0, mean = 0, max = 0;
    std::size_t count = 0;
};

struct QualitySummary {
    std::size_t hexes = 0, nodes = 0;
    Stats scaledJacobian;          // over non-degenerate hexes
    std::size_t inverted = 0;      // scaled Jacobian < 0
    std::size_t below02 = 0;       // scaled Jacobian < 0.2 (inverted included)
    std::size_t degenerate = 0;    // Verdict returned 1e30 (collapsed edge/axis)
    std::array<std::size_t, 11> histogram{};  // over kScaledJacobianBins; degenerate hexes not binned
    Stats inverseMeanRatio;        // over hexes where it is finite
    Stats condition;
    Stats edgeRatio;
    Stats volume;
    double totalVolume = 0;
};
QualitySummary summarize(const HexMesh& mesh, const HexQuality& q);

// A mesh read from `path` with more than half of its `hexes` inverted has, in
// all likelihood, its corners in mirrored order (another tool's hexahedron
// convention): throws isohex::Error naming the file, the count, VTK's order
// and `consequence` (what working on it would do), e.g. "smoothing would only
// scramble the mesh".
void refuseMirroredCornerOrder(const std::string& path, std::size_t inverted, std::size_t hexes,
                               const std::string& consequence);
nlohmann::json toJson(const QualitySummary& s);

}  // namespace isohex

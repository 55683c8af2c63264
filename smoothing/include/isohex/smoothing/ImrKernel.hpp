#pragma once
// The inverse mean ratio of a node's corner terms, four terms at a time.
//
// NodeObjective<InverseMeanRatio> spends most of a smoother visit in two
// loops over the node's 30 to 60 corner terms: derivatives() (value,
// gradient and Hessian of every term) and value(d) (every term at a trial
// displacement, once per line-search step). Each term is a few dozen
// independent multiplications and one inverse cube root, so the terms are
// computed in lanes of a 4-wide vector, with AVX2 where the processor has it.
//
// The result is the scalar code's to the last bit, on any processor: every
// lane performs the same IEEE operations in the same order as
// CornerMetrics.hpp's normDet and InverseMeanRatio (Eigen's own summation
// orders included; no fused multiply-add), and the terms are summed one by
// one in their order afterwards. So meshes do not change with this path, with
// the processor or with the thread count. tests/smoothing/test_metrics.cpp
// compares both instruction sets with the scalar code bit for bit.
#include <cstddef>

#include "isohex/smoothing/CornerMetrics.hpp"

namespace isohex::smoothing {

struct CornerTerm;

namespace detail {

// n, t, grad n, grad t and |w|^2 of each term (NormDet, structure of arrays),
// as of the last imrDerivatives; imrValue evaluates from them.
struct ImrState {
    static constexpr std::size_t kCapacity = 200;  // 40 hexes around a node; more take the scalar path
    alignas(32) double n[kCapacity];
    alignas(32) double t[kCapacity];
    alignas(32) double gn[3][kCapacity];
    alignas(32) double gt[3][kCapacity];
    alignas(32) double w2[kCapacity];
};

// Sum of the terms' inverse mean ratios with gradient g and Hessian H (with
// respect to the node's displacement), as NodeObjective::derivatives computes
// them; fills `state`. +inf (g and H meaningless) if a term has det <= 0.
// count <= ImrState::kCapacity.
double imrDerivatives(const CornerTerm* terms, std::size_t count, ImrState& state, Vector3& g, Matrix3& H);

// The sum at displacement d from the state's base position, as
// NodeObjective::value computes it from NormDet; +inf if a term is infeasible.
double imrValue(const ImrState& state, std::size_t count, const Vector3& d);

// The sum at displacement d computed from the frames themselves (each frame
// displaced, then its squared norm and determinant), as NodeObjective::value
// does before derivatives() has set up the state; +inf if a term is infeasible.
double imrFrameValue(const CornerTerm* terms, std::size_t count, const Vector3& d);

// Which instruction set the kernels use: "avx2" or "sse2". `useAvx2(false)`
// forces the baseline (tests); `useAvx2(true)` restores the processor's choice.
const char* imrInstructionSet();
void useAvx2(bool enable);

}  // namespace detail
}  // namespace isohex::smoothing

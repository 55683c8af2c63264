#pragma once
// Internal to smoothing/: a hex's 9 frames (its centre and its 8 corners) as
// signed combinations of its nodes, with each frame's scaled Jacobian (or
// scaled determinant) and its gradient with respect to the nodes, for the
// worst-hex pass's joint moves, which take a soft minimum over every frame of
// a region.
#include <array>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Quality.hpp"

namespace isohex::smoothing::detail {

// What the soft minimum needs of each of a hex's 9 frames: the scaled
// Jacobian and, to differentiate it, the columns, their lengths and their
// cross products. frameValues fills it once per step; frameGradients reuses
// it instead of forming the frames again.
struct FrameState {
    std::array<Vec3, 3> col, cross;  // cross = b x c, c x a, a x b
    double la, lb, lc, len, s;
    bool collapsed;
};
using HexFrames = std::array<FrameState, 9>;

// What the soft minimum is taken of, per frame: the scaled Jacobian (scale
// 0), or the determinant times `scale` (the frame's columns as in the
// corners; the centre frame's, sums of four edges, count a quarter each).
// The scaled Jacobian does not see size, so a region whose worst frames have
// been evened out at zero (a node on the plane of its neighbours, the
// corner hex of a sheet pressed flat against the surface) gives the ascent
// no direction that opens them; the determinant grows with the frame, so its
// soft minimum pushes the flat frames open first. Fills `out` with the
// scaled Jacobian of each of the 9 frames (-2 for a collapsed frame), or with
// scale > 0 its scaled determinant.
void frameValues(const HexCoords& x, HexFrames& out, double scale = 0);

// Adds weight[f] * d s_f / d x_n to grad[n] for the hex's 8 nodes (s_f as
// frameValues computed it with the same scale).
void frameGradients(const HexFrames& frames, const double* weight, std::array<Vec3, 8>& grad, double scale = 0);

}  // namespace isohex::smoothing::detail

#pragma once
// The background grid that `isohex mesh --method sheets` cuts with the sheets.
#include "isohex/core/HexMesh.hpp"

namespace isohex::insertion {

// A regular grid of cubes of edge `size` covering the box [lo, hi] grown by
// `margin` (a fraction of its extent) on every side; material 1. Nodes are
// numbered x fastest, then y, then z; hexes likewise.
HexMesh regularGrid(const Vec3& lo, const Vec3& hi, double size, double margin = 0.05);

}  // namespace isohex::insertion

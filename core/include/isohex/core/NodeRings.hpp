#pragma once
// The nodes within a few rings of hexes of some seed nodes: a band to
// optimise again around cut nodes (pipeline/CutBands.hpp), or the nodes a
// relaxation may move around the hexes it lifts (pipeline/MinQuality.cpp).
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"

namespace isohex {

// One flag per node of `mesh`: the flagged `seeds`, then `rings` times every
// node of a hex that has a flagged node.
std::vector<std::uint8_t> nodesWithinRings(const HexMesh& mesh, std::vector<std::uint8_t> seeds, int rings);

}  // namespace isohex

#pragma once
// The hexes the optimiser could not fix: inverted ones, and flat ones (not
// inverted, scaled Jacobian below a floor), with the warnings that name them.
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Quality.hpp"  // hexCentre, which the warnings use
#include "isohex/pipeline/StageSink.hpp"

namespace isohex::pipeline {

// Hexes with a corner or centre Jacobian determinant <= 0, by index.
std::vector<Index> invertedHexes(const HexMesh& mesh);

// The counts the report gives of a Stuck.
struct StuckCounts {
    std::size_t inverted = 0, flat = 0;
    double min = 0, minValid = 0;
};

// The inverted hexes (by index) and the flat ones, not inverted with a
// scaled Jacobian below the floor (or degenerate: an edge of zero length),
// worst first.
struct Stuck {
    std::vector<Index> inverted;
    std::vector<Index> flat;
    double min = std::numeric_limits<double>::infinity();       // over all hexes
    double minValid = std::numeric_limits<double>::infinity();  // over the hexes not inverted
    // Fewer inverted; or as many and, with a floor, fewer flat with a minimum
    // over the rest no lower, or as many flat with a higher one.
    bool betterThan(const Stuck& o, double floor) const;
    StuckCounts counts() const { return {inverted.size(), flat.size(), min, minValid}; }
};
Stuck stuckHexes(const HexMesh& mesh, double floor);

// Warns (through the sink) of the hexes still inverted at the end, the
// first's position, `more`, and what may avoid them; returns the text
// (empty when `left` is empty: no warning).
std::string warnInverted(StageSink& sink, const HexMesh& mesh, const std::vector<Index>& left,
                         std::size_t afterUntangling, const std::string& more, bool fixedBoundary,
                         bool byCompare = false);

// Warns of the flat hexes left (none: no warning); returns the text.
std::string warnFlat(StageSink& sink, const HexMesh& mesh, const Stuck& stuck, double floor, std::size_t meshedAgain,
                     int maxRetries);

}  // namespace isohex::pipeline

// Distances (in voxels of the scan) of the corners of every boundary quad
// against the outside to their isosurface, by kind of corner: the labels of
// its cell's 8 grid points differ from a fresh sampling of the scan
// (non-manifold repair or --keep-largest changed them; measured against the
// repaired field, and against the scan's for the record), or the move onto
// the surface inverted a hex so the pipeline starts it from a held-back
// position (ExtractStats::heldBack), or the cell holds three or more
// materials (measured against the union of the labels), or none of these
// ("plain").
#pragma once

#include <cstddef>
#include <string>

#include "ExtractionChecks.hpp"

namespace isohex::testsupport {

struct CornerFigures {
    std::size_t plain = 0, changed = 0, multi = 0, held = 0;
    std::size_t plainOver = 0, changedOver = 0, multiOver = 0, heldOver = 0;  // beyond 0.1 voxel
    double plainMax = 0, changedMax = 0, multiMax = 0, heldMax = 0, plainMean = 0, allMean = 0;
    // changed cells are measured against the repaired field (RepairedDomain);
    // how far their corners are from the scan's own isosurface, for the record
    std::size_t changedScanOver = 0;
    double changedScanMax = 0;
    std::size_t all() const { return plain + changed + multi + held; }
};

CornerFigures cornerDistances(const Extracted& r);

// Prints the figures with the prefix "[figures]".
void print(const std::string& name, const CornerFigures& c);

// Every boundary corner within 0.1 voxel of its isosurface: the scan's, the
// repaired field's in cells the repair changed, the union of the labels' where
// the outside meets two or more labels; held-back corners included (the mesh
// has them on the surface, their valid position is only in ExtractStats).
void expectOnTheIsosurface(const std::string& name, const CornerFigures& f);

}  // namespace isohex::testsupport

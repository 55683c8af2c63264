#pragma once
// Collapsing a dual sheet: removing one layer of hexes by merging the two
// ends of each of its edges.
#include <cstddef>
#include <set>
#include <string>

#include "isohex/core/Dual.hpp"
#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"

namespace isohex {

// Removes a sheet by collapsing its edges (seed 3.3.3.1). Refuses (throws
// isohex::Error saying why, mesh untouched) when that would merge nodes of two
// different surfaces or curves, pinch a surface (an edge between two nodes of
// one surface that runs through the solid), remove every hex of a material,
// or leave an invalid mesh. Returns the number of hexes removed. `topo` and
// `sheets` are those of `mesh` and are out of date afterwards.
std::size_t collapse(HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet);

// The kinds of topological defect (validate()'s keys other than inverted
// hexes) `mesh` has: what a collapse may keep but not add.
std::set<std::string> topologicalDefects(const HexMesh& mesh);

// The same, given topologicalDefects(mesh): a caller that tries several
// sheets of one mesh validates it once instead of once per attempt. With
// `defectsAfter`, a collapse that succeeds also gives topologicalDefects of
// the collapsed mesh (from the validation it made anyway), so a loop of
// collapses never validates a mesh twice.
std::size_t collapse(HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet,
                     const std::set<std::string>& defectsBefore, std::set<std::string>* defectsAfter = nullptr);

}  // namespace isohex

#pragma once
// The dual of a hex mesh (seed chapter 2.3): sheets and chords.
//
// A sheet is a class of edges linked through opposite (parallel) edges of hexes;
// its hexes form one layer of the mesh. A chord is a class of quads linked
// through opposite faces of hexes; its hexes form one stack.
#include <vector>

#include "isohex/core/Topology.hpp"

namespace isohex {

struct DualSheets {
    std::vector<Index> edgeSheet;   // per edge, its sheet id
    Csr sheetEdges;                 // sheet -> edges (sorted)
    Csr sheetHexes;                 // sheet -> hexes (sorted, unique; a self-intersecting sheet lists a hex once)
    std::vector<std::array<Index, 3>> hexSheets;  // per hex, sheet of its xi, eta, zeta edges
    std::size_t count() const { return sheetEdges.rows(); }
};

struct DualChords {
    std::vector<Index> quadChord;   // per quad, its chord id
    Csr chordQuads;                 // chord -> quads (sorted)
    Csr chordHexes;                 // chord -> hexes (sorted, unique)
    std::vector<std::array<Index, 3>> hexChords;  // per hex, chord through faces (0,1), (2,3), (4,5)
    std::size_t count() const { return chordQuads.rows(); }
};

// Ids are numbered by the smallest edge (quad) of each class, so they do not
// depend on the thread count.
DualSheets buildSheets(const HexMesh& mesh, const Topology& topo);
DualChords buildChords(const HexMesh& mesh, const Topology& topo);

}  // namespace isohex

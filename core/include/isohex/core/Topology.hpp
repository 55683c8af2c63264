#pragma once
// Derived topology of a HexMesh, built in linear time and in parallel.
//
// Node-to-hex adjacency is a counting sort (O(n)). A face's hexes are then
// found by intersecting the adjacency rows of the ends of one of its
// diagonals, an edge's from the rows of its two ends (constant work each).
// Every quad and edge is owned by its smallest hex and numbered in owner
// order, so ids are the same for any thread count.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "isohex/core/Csr.hpp"
#include "isohex/core/HexMesh.hpp"

namespace isohex {

// A unique quadrilateral. `nodes` are in the order hex[0] sees them, so the
// right-hand normal points out of hex[0]. hex[1] is kNone on the boundary.
// Quads found in more than two hexes (an invalid mesh) keep their first two in
// hex[] and are listed in Topology::overfullQuads.
struct Quad {
    std::array<Index, 4> nodes;
    std::array<Index, 2> hex{kNone, kNone};
    std::array<std::int8_t, 2> localFace{-1, -1};
    bool boundary() const { return hex[1] == kNone; }
};

struct Topology {
    std::vector<Quad> quads;
    std::vector<std::array<Index, 6>> hexQuads;      // per hex, quad id of local face f
    std::vector<std::array<Index, 2>> edges;         // unique edges, (smaller node, larger node)
    std::vector<std::array<Index, 12>> hexEdges;     // per hex, edge id of local edge e
    Csr nodeHexes;                                   // node -> hexes using it (sorted)
    Csr quadHexesAll;                                // quad -> every hex holding it (normally 1 or 2)
    std::vector<Index> boundaryQuads;                // quads with exactly one hex
    std::vector<Index> interfaceQuads;               // quads between two hexes of different material
    std::vector<Index> overfullQuads;                // quads in more than two hexes (invalid)
    std::vector<std::uint8_t> nodeOnBoundary;        // 1 if the node touches a boundary quad
    std::vector<Index> boundaryNodes;                // sorted
};

// What buildTopology fills. `NodeMoves` leaves hexEdges and quadHexesAll
// empty (48 bytes per hex and about 40 more at peak, on 2 M hexes about 160 MB):
// moving nodes (the smoother, the worst-hex pass) reads neither; every other
// field is the same as with `All`. `QuadHolders` leaves edges and hexEdges
// empty instead (addHexEdges adds them): validate() checks the volume with
// the quads' holders, drops them, then checks the surfaces with the edges, so
// the two largest parts are never held together and each is built once.
// `Surfaces` fills nodeHexes, nodeOnBoundary, boundaryNodes and, in `quads`,
// only the boundary and interface quads (boundaryQuads and interfaceQuads
// index them; in the order they have among all quads); hexQuads, edges,
// hexEdges, quadHexesAll and overfullQuads stay empty (validate() keeps the
// same, collected in its own pass over the hexes). `SurfaceMoves` adds
// the edges: what moving nodes reads (the smoother, the worst-hex pass),
// without the interior quads and the per-hex quad ids; on a brain about 65
// bytes per hex instead of NodeMoves' 170, and no per-hex face links while
// it is built.
enum class TopologyParts : std::uint8_t { All, NodeMoves, QuadHolders, Surfaces, SurfaceMoves };

// Builds the fields of Topology that `parts` names. Hexes with repeated nodes
// still get their faces and edges (validate() reports them); indices out of
// range throw.
Topology buildTopology(const HexMesh& mesh, TopologyParts parts = TopologyParts::All);

// Throws isohex::Error, naming `who`, if `topo` was not built for this mesh
// (its hex or node counts differ) or lacks a part `parts` has (All: every
// part; NodeMoves: the edges; QuadHolders: the quads' holders): for
// functions that take a prebuilt topology instead of building their own.
void requireTopologyOf(const HexMesh& mesh, const Topology& topo, const std::string& who,
                       TopologyParts parts = TopologyParts::NodeMoves);

// On a topology of `mesh` built with fewer parts, a part it left empty, as
// buildTopology(mesh) gives it: quadHexesAll (on a NodeMoves topology), or
// edges with hexEdges (on a QuadHolders one, or on a NodeMoves one, whose
// edges are numbered again to the same values). For work that needs the two
// one after the other and not both at once (validate adds the edges).
void addQuadHolders(Topology& topo, const HexMesh& mesh);
void addHexEdges(Topology& topo, const HexMesh& mesh);

// The id of the edge joining nodes a and b, or kNone if no hex has that edge.
// Needs a topology built with TopologyParts::All (throws otherwise).
Index edgeBetween(const HexMesh& mesh, const Topology& topo, Index a, Index b);

// The surfaces a mesh exposes: boundary quads grouped by (material inside,
// -1), and interface quads grouped by (smaller material, larger material).
// Sorted by (inside, outside) so ids are stable.
struct SurfacePatch {
    SurfaceTag tag;
    std::vector<Index> quads;                      // quad ids
    std::vector<std::pair<Index, int>> hexFaces;   // (hex, local face) seen from `tag.inside`
};
std::vector<SurfacePatch> surfacePatches(const HexMesh& mesh, const Topology& topo);

}  // namespace isohex

namespace isohex {
// Sets mesh.surfaces to the surfaces the mesh exposes (surfacePatches order)
// and classifies nodes: a node on one surface gets NodeKind::Surface with that
// surface's id, a node on two or more gets NodeKind::Curve; other nodes become
// Interior. Fixed nodes stay fixed.
void classifyBoundaryNodes(HexMesh& mesh);
}  // namespace isohex

#pragma once
// Inserting two sheets of hexes along a closed triangle surface into an
// existing hex mesh (seed section 5.4, steps 1-4, with chapter 7's
// improvements), and capturing several surfaces and the curves where they
// meet by successive insertions (seed chapter 6).
//
//   1. hexes with an edge crossing a triangle (AABB tree) are "intersected";
//   2. the others are flood-filled into face-connected groups, each on one
//      side of the surface: Side1 = inside, Side2 = outside;
//   3. intersected hexes join a side (auto: the side their centroid is on),
//      then hexes are moved across until the boundary of each side is a
//      closed 2-manifold (no edge in more than two of its quads and no node
//      where two parts of it touch);
//   4. every node of the interface between the sides is split in three: the
//      middle copy goes to the closest point of the triangles (or, where the
//      interface reaches the mesh's boundary, to the curve where the surface
//      meets that boundary), each side takes one of the outer copies, and one
//      new hex per interface quad on each side makes the two sheets.
#include <cstddef>
#include <cstdint>
#include <memory>

#include "isohex/core/HexMesh.hpp"
#include "isohex/insertion/SheetGeometry.hpp"
#include "isohex/insertion/TriangleTree.hpp"

namespace isohex::insertion {

// Which side the hexes cut by the surface join (Side1 = inside the surface).
enum class Intersected { Auto, Side1, Side2 };
// Which side of the surface the mesh keeps, with its sheet.
enum class Keep { Inside, Outside, Both };

struct InsertOptions {
    Intersected intersected = Intersected::Auto;
    Keep keep = Keep::Both;
    // Move the middle nodes onto the surface (and curves). Off: they stay
    // where the mesh had them, so extracting the sheets restores the mesh.
    bool project = true;
    // With Keep::Both, the material of the inside hexes: -1 = one more than
    // the largest material in the mesh (so the surface is a material
    // interface); the outside hexes keep theirs.
    std::int32_t insideMaterial = -1;
    // The outer copies start this fraction of the local edge length from the
    // middle copy, along the surface normal.
    double offset = 0.3;
    int maxRepairRounds = 500;
};

struct InsertResult {
    std::size_t intersectedHexes = 0;
    std::size_t side1Hexes = 0, side2Hexes = 0;  // after assigning the intersected hexes and repair
    std::size_t floodComponents = 0;
    std::size_t nonManifoldEdgesFixed = 0, nonManifoldNodesFixed = 0, hexesMoved = 0;
    std::size_t interfaceQuads = 0, splitNodes = 0;
    std::size_t surfaceNodes = 0, curveNodes = 0, fixedNodes = 0;
    std::size_t sheetHexes = 0;                  // new hexes kept
    std::size_t removedHexes = 0;                // with keep inside/outside
    std::int32_t surfaceId = -1;                 // index of the new surface in HexMesh::surfaces
    double seconds = 0;
};

// Inserts the two sheets along `surface` (a closed triangle surface) into
// `mesh` and records the new surface and curves in `geometry`. Throws
// isohex::Error (mesh and geometry untouched) if the surface crosses no hex
// edge of the mesh, one side ends up empty, or the sides are not manifold
// after `maxRepairRounds` rounds. Deterministic for any thread count.
InsertResult insertSheets(HexMesh& mesh, SheetGeometry& geometry, std::shared_ptr<const TriangleTree> surface,
                          const InsertOptions& options = {});

}  // namespace isohex::insertion

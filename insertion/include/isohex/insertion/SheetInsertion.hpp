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
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/insertion/TriangleTree.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::insertion {

// Where the mesh's surfaces and curves are: the projector the smoother uses,
// filled as surfaces are inserted. Surface s of the mesh lies on
// trees[surfaceTree[s]]; curve c is where trees[curves[c][0]] and
// trees[curves[c][1]] meet (found by alternating closest-point projections).
struct SheetGeometry final : smoothing::SurfaceProjector {
    std::vector<std::shared_ptr<const TriangleTree>> trees;
    std::vector<std::int32_t> surfaceTree;          // per HexMesh::surfaces entry, -1 = unknown
    std::vector<std::array<std::int32_t, 2>> curves;

    Vec3 project(std::int32_t surfaceId, const Vec3& x) const override;
    bool hasCurves() const override { return true; }
    Vec3 projectToCurve(std::int32_t curveId, const Vec3& x) const override;
    // The point on both trees a and b nearest x (alternating projections).
    Vec3 projectToIntersection(std::int32_t a, std::int32_t b, const Vec3& x) const;
    std::int32_t addTree(std::shared_ptr<const TriangleTree> tree);
};

// Makes the surfaces of a mesh read from a file surfaces the smoother can
// keep nodes on: classifies boundary nodes (classifyBoundaryNodes), puts the
// quads of each surface (outer boundary per material, interfaces between
// materials; two triangles a quad) in a tree of its own, and fixes nodes on
// sharp boundary edges (dihedral angle above `featureAngleDegrees`) and on
// curves between existing surfaces, whose geometry is not known. Returns the
// number of nodes fixed.
std::size_t adoptBoundary(HexMesh& mesh, SheetGeometry& geometry, double featureAngleDegrees = 30.0);

enum class Intersected { Auto, Side1, Side2 };  // Side1 = inside the surface
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
// isohex::Error (mesh untouched) if the surface crosses no hex edge of the
// mesh or one side ends up empty. Deterministic for any thread count.
InsertResult insertSheets(HexMesh& mesh, SheetGeometry& geometry, std::shared_ptr<const TriangleTree> surface,
                          const InsertOptions& options = {});

// A regular grid of cubes of edge `size` covering the box [lo, hi] grown by
// `margin` (a fraction of its extent) on every side; material 1.
HexMesh regularGrid(const Vec3& lo, const Vec3& hi, double size, double margin = 0.05);

}  // namespace isohex::insertion

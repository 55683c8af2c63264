#pragma once
// The geometry a mesh's surfaces and curves lie on, as the smoother sees it:
// a smoothing::SurfaceProjector over triangle trees, filled as sheets are
// inserted (SheetInsertion.hpp) or, for a mesh read from a file, from the
// mesh's own boundary (adoptBoundary).
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/insertion/TriangleTree.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::insertion {

// Surface s of the mesh lies on trees[surfaceTree[s]]; curve c is where
// trees[curves[c][0]] and trees[curves[c][1]] meet (found by alternating
// closest-point projections).
struct SheetGeometry final : smoothing::SurfaceProjector {
    std::vector<std::shared_ptr<const TriangleTree>> trees;
    std::vector<std::int32_t> surfaceTree;          // per HexMesh::surfaces entry, -1 = unknown
    std::vector<std::array<std::int32_t, 2>> curves;

    Vec3 project(std::int32_t surfaceId, const Vec3& x) const override;
    bool hasCurves() const override { return true; }
    Vec3 projectToCurve(std::int32_t curveId, const Vec3& x) const override;
    // The point on both trees a and b nearest x (alternating projections).
    Vec3 projectToIntersection(std::int32_t a, std::int32_t b, const Vec3& x) const;
    // The point where `surface` crosses curve `curveId`: on all three
    // surfaces (alternating projections onto surface, then the curve's two
    // trees).
    Vec3 projectToCurveCrossing(std::int32_t curveId, const TriangleTree& surface, const Vec3& x) const;
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

}  // namespace isohex::insertion

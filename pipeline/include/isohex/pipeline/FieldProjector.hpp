#pragma once
// Projection onto the scan's surfaces for the optimiser and the fidelity
// measurement: surface nodes onto the zero set of the inside material's field
// (against the exterior) or of f_a - f_b (between two materials), curve nodes
// onto the crossing of two such surfaces.
#include <array>
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/octree/RepairedDomain.hpp"
#include "isohex/pipeline/SelectionDomain.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::pipeline {

class FieldProjector : public smoothing::SurfaceProjector {
public:
    // With `repaired` (the extraction's RepairedDomain), points in cells around
    // a grid point the repair changed go onto its zero set, the surface the
    // mesh was extracted on there.
    FieldProjector(const SelectionDomain& d, const HexMesh& mesh, const octree::RepairedDomain* repaired = nullptr)
        : domain_(d), surfaces_(mesh.surfaces), curves_(mesh.curves), repaired_(repaired) {}

    // Newton steps onto the surface, each at most half a voxel; a point that
    // would travel more than 3 voxels, or that ends off the zero set, is
    // answered with NaN (the smoother rejects such a move).
    Vec3 project(std::int32_t surfaceId, const Vec3& x) const override;
    // The box around a meshed exterior is no isosurface: project() leaves
    // its nodes where they are.
    bool projectsOnto(std::int32_t surfaceId) const override;

    // Curves where three materials meet (HexMesh::curves): where all three
    // are materials, f_p = f_q = f_r (the crossing of their interfaces, as
    // project() has them); against the outside, the union's isosurface
    // (where extraction put the vertices of such cells) crossed with the
    // interface of the other two. Levenberg-Marquardt; NaN where it does not
    // settle on both within 3 voxels.
    bool hasCurves() const override { return !curves_.empty(); }
    Vec3 projectToCurve(std::int32_t curveId, const Vec3& x0) const override;

private:
    Vec3 projectRepaired(std::int32_t a, std::int32_t b, const Vec3& x) const;
    Vec3 projectDifference(std::int32_t a, std::int32_t b, const Vec3& x0) const;

    const SelectionDomain& domain_;
    std::vector<SurfaceTag> surfaces_;
    std::vector<std::array<std::int32_t, 3>> curves_;
    const octree::RepairedDomain* repaired_ = nullptr;
};

}  // namespace isohex::pipeline

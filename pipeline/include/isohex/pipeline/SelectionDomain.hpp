#pragma once
// The scan as the grid stages see it (octree::Domain): the material at a
// point (a label lookup for label maps, the sign of the field for intensity)
// and each selected material's implicit field.
#include <cstdint>
#include <map>
#include <memory>
#include <vector>

#include <openvdb/openvdb.h>

#include "isohex/imaging/Selection.hpp"
#include "isohex/imaging/Volume.hpp"
#include "isohex/octree/Domain.hpp"

namespace isohex::pipeline {

class SelectionDomain : public octree::Domain {
public:
    SelectionDomain(std::shared_ptr<const imaging::Volume> v, std::shared_ptr<const imaging::Selection> s);
    std::int32_t materialAt(const Vec3& x) const override;
    double value(std::int32_t material, const Vec3& x, Vec3* gradient) const override;
    // Intensity: the one material's field. Labels: 0.5 minus the trilinear
    // interpolation of the indicator of "any selected label" (the union's own
    // 0.5-isosurface, the reference fidelity() and the tests use for the
    // labelled region's volume).
    double unionValue(const Vec3& x, Vec3* gradient) const override;
    std::int32_t materialOtherThan(std::int32_t material, const Vec3& x) const override;
    // The field of a selected material; throws for any other.
    const imaging::ImplicitField& field(std::int32_t material) const;

private:
    // The voxel cell of the label grid that holds x: the index of its lower
    // corner voxel and x's position in it, each coordinate in [0, 1) (the
    // trilinear weights of the 8 voxels around x).
    struct VoxelCell {
        openvdb::Coord lower;
        openvdb::Vec3d t;
    };
    VoxelCell voxelCell(const Vec3& x) const;
    // The label whose trilinear indicator weight at x is largest (unselected
    // labels count as background), the nearest voxel's label among equals.
    std::int32_t labelAt(const Vec3& x) const;
    bool isSelected(std::int32_t label) const;

    std::shared_ptr<const imaging::Volume> volume_;
    std::shared_ptr<const imaging::Selection> selection_;
    std::map<std::int32_t, std::size_t> slot_;
    std::int32_t firstLabel_ = 0;
    std::vector<std::uint8_t> selectedFlag_;  // empty: ids too far apart, use slot_
};

}  // namespace isohex::pipeline

#pragma once
// The field the repaired labels are the signs of. Non-manifold repair and
// --keep-largest change the material of some grid points against the sign of
// the scan's field there, so no surface of the scan crosses the cells around
// such a point and dual contouring has nowhere on the scan's isosurface to put
// their vertices. This domain is the scan's field plus, for each changed grid
// point p and each material whose sign at p disagrees with p's new label, a
// trilinear hat over the 8 cells around p (1 at p, 0 at every other grid
// point) scaled so that the value at p becomes the mirror image of the scan's
// value (-f(p), or a tenth of the field's local step if f(p) is nearly 0).
// Every grid point then has its label's sign, the field is unchanged farther
// than one grid step from a changed point, and the surface crosses every cell
// between two labels. The same for the union of the materials (unionValue)
// where a point left or joined it. materialAt and materialOtherThan are the scan's.
#include <array>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <vector>

#include "isohex/octree/Labels.hpp"

namespace isohex::octree {

class RepairedDomain : public Domain {
public:
    // `sampled` are the labels as sampleLabels gave them, `repaired` the same
    // grid after keepLargestComponents and repairNonManifold. `base` must
    // outlive this object.
    RepairedDomain(const Domain& base, const Labels& sampled, const Labels& repaired);
    std::int32_t materialAt(const Vec3& x) const override { return base_.materialAt(x); }
    double value(std::int32_t material, const Vec3& x, Vec3* gradient = nullptr) const override;
    double unionValue(const Vec3& x, Vec3* gradient = nullptr) const override;
    // Itself in cells with a changed grid point, the scan's domain elsewhere
    // (where the two are equal).
    const Domain& within(const Vec3& x) const override { return nearChange(x) ? *this : base_.within(x); }
    std::int32_t materialOtherThan(std::int32_t material, const Vec3& x) const override {
        return base_.materialOtherThan(material, x);
    }
    // Grid points whose field was changed (those with a hat).
    std::size_t changedPoints() const { return changedCount_; }
    // Whether any of the 8 grid points of the cell holding x carries a hat.
    bool nearChange(const Vec3& x) const;

private:
    const Domain& base_;
    Grid grid_;
    std::array<std::array<double, 3>, 3> toGrid_;  // world offset -> grid coordinates
    std::vector<std::uint8_t> changed_;             // per grid point
    std::vector<std::uint8_t> hatCell_;             // per cell, by its lowest grid point
    std::unordered_map<std::uint64_t, double> hat_; // (point, material) -> hat height
    std::size_t changedCount_ = 0;
    // hats of the union of all materials are stored under this material id
    static constexpr std::int32_t kUnion = std::numeric_limits<std::int32_t>::min();
    std::array<double, 3> gridCoords(const Vec3& x) const;
    bool cellHasHat(int i0, int j0, int k0) const;
    double at(std::int32_t material, const Vec3& x, Vec3* gradient) const;  // the base's field
    double withHats(std::int32_t material, const Vec3& x, Vec3* gradient) const;
};

}  // namespace isohex::octree

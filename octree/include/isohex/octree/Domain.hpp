#pragma once
// What the mesher needs to know about the solid: which material a point is
// in, and a signed function per material (negative inside) with its gradient
// for Hermite data. The pipeline implements this over the scan's OpenVDB
// fields; tests implement it analytically. Must be safe to call from many
// threads at once.
#include <cstdint>
#include <limits>

#include "isohex/core/HexMesh.hpp"

namespace isohex::octree {

class Domain {
public:
    virtual ~Domain() = default;
    // Material at x; 0 = background (outside every selected material).
    virtual std::int32_t materialAt(const Vec3& x) const = 0;
    // Signed function of one material (< 0 inside it), world units or intensity
    // units; only its zero set and the direction of its gradient matter.
    virtual double value(std::int32_t material, const Vec3& x, Vec3* gradient = nullptr) const = 0;
    // Signed function of the union of all materials (< 0 inside any of them),
    // with its gradient: the outer boundary where two or more materials meet
    // it (label maps: the surface of the labelled region as a whole, which the
    // materials' own surfaces leave gaps in). NaN when not known: such
    // vertices then stay at their QEF point.
    virtual double unionValue(const Vec3& x, Vec3* gradient = nullptr) const {
        (void)x;
        (void)gradient;
        return std::numeric_limits<double>::quiet_NaN();
    }
    // The domain to ask about points of the extraction grid's cell holding x
    // (x its centre): one that changes the field only near some grid points
    // answers with the domain underneath elsewhere, so the many queries of a
    // cell skip its bookkeeping. Default: this domain.
    virtual const Domain& within(const Vec3& x) const {
        (void)x;
        return *this;
    }
    // The material x would belong to if it were not in `material` (for
    // non-manifold repair that removes a point from a region). Default: 0.
    virtual std::int32_t materialOtherThan(std::int32_t material, const Vec3& x) const {
        (void)material;
        (void)x;
        return 0;
    }
};

}  // namespace isohex::octree

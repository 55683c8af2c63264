#pragma once
// How the smoother learns where a surface is, without depending on the module
// that knows (imaging's ImplicitField, an analytic shape in tests, a CAD kernel).
#include <cstdint>

#include "isohex/core/HexMesh.hpp"

namespace isohex::smoothing {

struct SurfaceProjector {
    virtual ~SurfaceProjector() = default;
    // The point of surface `surfaceId` (an index into HexMesh::surfaces, as in
    // NodeClass::id) closest to `x`. Called concurrently from several threads,
    // so it must be thread-safe, and deterministic so that smoothing results do
    // not depend on the thread count.
    virtual Vec3 project(std::int32_t surfaceId, const Vec3& x) const = 0;

    // Whether surface `surfaceId` is one the projector finds (an isosurface,
    // an analytic shape): true by default. A projector that leaves the nodes
    // of some surface where they are (project answers x itself, as for the
    // box around a meshed exterior) answers false for it, and the worst-hex
    // pass's surface slack then keeps those nodes on their surface instead
    // of letting them move off it by what would look like no distance.
    virtual bool projectsOnto(std::int32_t surfaceId) const {
        (void)surfaceId;
        return true;
    }

    // Curves (NodeKind::Curve, NodeClass::id names the curve): a projector
    // that knows them answers true here and gives the point of curve
    // `curveId` closest to `x`; the smoother then slides curve nodes along
    // their curve. Projectors that do not (the default) keep curve nodes fixed.
    virtual bool hasCurves() const { return false; }
    virtual Vec3 projectToCurve(std::int32_t curveId, const Vec3& x) const {
        (void)curveId;
        return x;
    }
};

}  // namespace isohex::smoothing

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
};

}  // namespace isohex::smoothing

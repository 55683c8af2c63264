#pragma once
// The implicit description of one material's boundary in world coordinates.
//
// Convention (as for OpenVDB level sets): value < 0 inside, > 0 outside, the
// surface is the zero set. For an intensity selection the value is
// (iso - intensity), or (intensity - iso) with "inside below", so its units
// are intensity units, not millimetres; for a surface it is a signed distance.
//
// Thread safety: queries use read-only, unregistered accessors that belong to
// the calling thread (each thread keeps one for the last few fields it
// queried, so consecutive queries near each other skip the descent from the
// tree's root), so any number of threads may query one field at once. The
// grid is never modified after construction.
#include <cstdint>

#include <openvdb/openvdb.h>

#include "isohex/core/HexMesh.hpp"  // Vec3

namespace isohex::imaging {

enum class Interpolation { Trilinear, Quadratic };

struct ProjectOptions {
    // Longest single step, in voxels (of the smallest spacing). Steps this
    // short cannot cross a feature thicker than a voxel unnoticed.
    double maxStepVoxels = 0.5;
    // Give up beyond this distance from the start point, in voxels.
    double maxDistanceVoxels = 8.0;
    // Converged when the estimated distance |f|/|grad f| to the surface is
    // below this many voxels.
    double toleranceVoxels = 1e-4;
    int maxIterations = 100;
};

struct Projection {
    Vec3 point{0, 0, 0};     // on the surface when `converged`, else the best point found
    bool converged = false;
    double distance = 0.0;   // |point - start| in world units
    int iterations = 0;
};

class ImplicitField {
public:
    ImplicitField() = default;
    // `grid` must not be modified afterwards (it is shared, not copied).
    explicit ImplicitField(openvdb::FloatGrid::ConstPtr grid,
                           Interpolation interpolation = Interpolation::Trilinear);

    bool valid() const { return static_cast<bool>(grid_); }
    double value(const Vec3& world) const;
    // World-space gradient (chain rule through the affine transform).
    Vec3 gradient(const Vec3& world) const;
    // Both at once, cheaper than two calls.
    double valueAndGradient(const Vec3& world, Vec3& gradient) const;
    bool inside(const Vec3& world) const { return value(world) < 0.0; }

    // A point on the zero set near `world`: Newton steps along the gradient,
    // each at most maxStepVoxels long; as soon as a step changes the sign the
    // root is pinned on that segment by Newton safeguarded with bisection, so
    // the result is the first crossing along the path and never a distant
    // part of the surface.
    Projection projectDetailed(const Vec3& world, const ProjectOptions& options = {}) const;
    // Shorthand: the projected point (the best point found when not converged).
    Vec3 project(const Vec3& world) const { return projectDetailed(world).point; }

    const openvdb::FloatGrid& grid() const { return *grid_; }
    openvdb::FloatGrid::ConstPtr gridPtr() const { return grid_; }
    Interpolation interpolation() const { return interpolation_; }
    double voxelSize() const { return voxelSize_; }  // smallest spacing, world units
    // World-space bounds of the region where the field is stored (outside it
    // the field is the constant background, i.e. outside).
    void bounds(Vec3& lo, Vec3& hi) const;

private:
    Vec3 toIndex(const Vec3& world) const;
    double sampleIndex(const openvdb::Vec3d& ijk, openvdb::Vec3d* gradIndex) const;

    openvdb::FloatGrid::ConstPtr grid_;
    Interpolation interpolation_ = Interpolation::Trilinear;
    double a_[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};     // world = origin + A * index
    double inv_[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};   // index = inv * (world - origin)
    double origin_[3] = {0, 0, 0};
    double voxelSize_ = 1.0;
    std::uint64_t id_ = 0;  // identifies the grid for the per-thread accessors
};

}  // namespace isohex::imaging

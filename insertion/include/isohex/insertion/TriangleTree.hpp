#pragma once
// A closed triangle surface in an AABB tree (CGAL's AABB_tree over a
// Surface_mesh, kept private to the .cpp): closest points, segment and box
// tests, and inside/outside by ray casting (CGAL::Side_of_triangle_mesh).
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "isohex/core/HexMesh.hpp"

namespace isohex::insertion {

class TriangleTree {
public:
    // Triangles index `vertices`; `name` is used in messages and as the
    // surface's name in written meshes. Throws isohex::Error if empty.
    TriangleTree(std::vector<Vec3> vertices, std::vector<std::array<std::int32_t, 3>> triangles, std::string name);
    ~TriangleTree();
    TriangleTree(const TriangleTree&) = delete;
    TriangleTree& operator=(const TriangleTree&) = delete;

    // Thread-safe (the tree and its distance-query search tree are built in
    // the constructor) and deterministic.
    Vec3 closestPoint(const Vec3& x) const;
    double squaredDistance(const Vec3& x) const;
    bool segmentCrosses(const Vec3& a, const Vec3& b) const;
    bool boxTouches(const Vec3& lo, const Vec3& hi) const;

    // Whether x lies inside the surface (meaningful for closed surfaces).
    // Not thread-safe (CGAL's ray caster keeps state); call from one thread.
    bool inside(const Vec3& x) const;

    // A place where two triangles that share no vertex or edge intersect
    // (the centroid of the first such pair CGAL finds), or nothing when the
    // surface does not cross itself. O(n log n) in the triangles.
    std::optional<Vec3> selfIntersection() const;

    const std::string& name() const { return name_; }
    const std::vector<Vec3>& vertices() const { return vertices_; }
    const std::vector<std::array<std::int32_t, 3>>& triangles() const { return triangles_; }
    std::array<Vec3, 2> bounds() const;   // min, max corner
    double meanEdgeLength() const;
    double volume() const;                // signed, divergence theorem (positive for outward triangles)

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    std::vector<Vec3> vertices_;
    std::vector<std::array<std::int32_t, 3>> triangles_;
    std::string name_;
};

}  // namespace isohex::insertion

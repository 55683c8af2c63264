#include "isohex/insertion/TriangleTree.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex::insertion {

namespace {
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
using Primitive = CGAL::AABB_face_graph_triangle_primitive<SurfaceMesh>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;
using Side = CGAL::Side_of_triangle_mesh<SurfaceMesh, K>;

Point toPoint(const Vec3& p) { return Point(p[0], p[1], p[2]); }
}  // namespace

struct TriangleTree::Impl {
    SurfaceMesh mesh;
    Tree tree;
    std::unique_ptr<Side> side;
};

TriangleTree::TriangleTree(std::vector<Vec3> vertices, std::vector<std::array<std::int32_t, 3>> triangles,
                           std::string name)
    : impl_(std::make_unique<Impl>()), vertices_(std::move(vertices)), triangles_(std::move(triangles)),
      name_(std::move(name)) {
    if (triangles_.empty()) throw Error(name_ + ": the surface has no triangles");
    std::vector<SurfaceMesh::Vertex_index> vi;
    vi.reserve(vertices_.size());
    for (const Vec3& p : vertices_) vi.push_back(impl_->mesh.add_vertex(toPoint(p)));
    for (const auto& t : triangles_) {
        for (std::int32_t i : t)
            if (i < 0 || static_cast<std::size_t>(i) >= vertices_.size())
                throw Error(name_ + ": a triangle names vertex " + std::to_string(i) + " of " +
                            std::to_string(vertices_.size()));
        // add_face refuses non-manifold or badly oriented faces; Side_of_triangle_mesh
        // only needs the triangles, so fall back to a detached copy of the face.
        if (impl_->mesh.add_face(vi[t[0]], vi[t[1]], vi[t[2]]) == SurfaceMesh::null_face()) {
            auto a = impl_->mesh.add_vertex(toPoint(vertices_[t[0]]));
            auto b = impl_->mesh.add_vertex(toPoint(vertices_[t[1]]));
            auto c = impl_->mesh.add_vertex(toPoint(vertices_[t[2]]));
            impl_->mesh.add_face(a, b, c);
        }
    }
    impl_->tree.insert(faces(impl_->mesh).first, faces(impl_->mesh).second, impl_->mesh);
    impl_->tree.build();
    impl_->tree.accelerate_distance_queries();
    impl_->side = std::make_unique<Side>(impl_->tree);
}

TriangleTree::~TriangleTree() = default;

std::optional<Vec3> TriangleTree::selfIntersection() const {
    using Face = SurfaceMesh::Face_index;
    std::vector<std::pair<Face, Face>> pairs;
    CGAL::Polygon_mesh_processing::self_intersections(impl_->mesh, std::back_inserter(pairs),
                                                      CGAL::parameters::maximum_number(1));
    if (pairs.empty()) return std::nullopt;
    Vec3 c{0, 0, 0};
    for (const auto v : CGAL::vertices_around_face(impl_->mesh.halfedge(pairs.front().first), impl_->mesh)) {
        const Point& p = impl_->mesh.point(v);
        c[0] += p.x() / 3;
        c[1] += p.y() / 3;
        c[2] += p.z() / 3;
    }
    return c;
}

Vec3 TriangleTree::closestPoint(const Vec3& x) const {
    const Point p = impl_->tree.closest_point(toPoint(x));
    return {p.x(), p.y(), p.z()};
}

double TriangleTree::squaredDistance(const Vec3& x) const { return impl_->tree.squared_distance(toPoint(x)); }

bool TriangleTree::segmentCrosses(const Vec3& a, const Vec3& b) const {
    return impl_->tree.do_intersect(K::Segment_3(toPoint(a), toPoint(b)));
}

bool TriangleTree::boxTouches(const Vec3& lo, const Vec3& hi) const {
    return impl_->tree.do_intersect(CGAL::Bbox_3(lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]));
}

bool TriangleTree::inside(const Vec3& x) const { return (*impl_->side)(toPoint(x)) != CGAL::ON_UNBOUNDED_SIDE; }

std::array<Vec3, 2> TriangleTree::bounds() const {
    Vec3 lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            std::numeric_limits<double>::infinity()};
    Vec3 hi{-lo[0], -lo[1], -lo[2]};
    for (const auto& t : triangles_)
        for (std::int32_t i : t)
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], vertices_[i][k]);
                hi[k] = std::max(hi[k], vertices_[i][k]);
            }
    return {lo, hi};
}

double TriangleTree::meanEdgeLength() const {
    double sum = 0;
    for (const auto& t : triangles_)
        for (int e = 0; e < 3; ++e) {
            using vec::operator-;
            sum += vec::norm(vertices_[t[e]] - vertices_[t[(e + 1) % 3]]);
        }
    return sum / (3.0 * static_cast<double>(triangles_.size()));
}

double TriangleTree::volume() const {
    double v = 0;
    for (const auto& t : triangles_) {
        v += vec::dot(vertices_[t[0]], vec::cross(vertices_[t[1]], vertices_[t[2]]));
    }
    return v / 6.0;
}

}  // namespace isohex::insertion

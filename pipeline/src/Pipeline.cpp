#include "isohex/pipeline/Pipeline.hpp"
#include "isohex/pipeline/SheetMethod.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <cctype>
#include <filesystem>
#include <limits>
#include <optional>
#include <sstream>

#include <sys/resource.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Sheets.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/imaging/Surface.hpp"
#include "isohex/octree/RepairedDomain.hpp"
#include "isohex/smoothing/ImrKernel.hpp"
#include "isohex/smoothing/Optimize.hpp"
#include "isohex/smoothing/WorstHexes.hpp"

namespace isohex::pipeline {

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Times a stage and reports it to the sink.
class Stage {
public:
    Stage(StageSink& sink, std::string name) : sink_(sink), name_(std::move(name)), start_(Clock::now()) {
        sink_.begin(name_);
    }
    double finish() {
        const double s = since(start_);
        sink_.end(name_, s);
        return s;
    }
    // A stage left by an exception is not reported as done; the error says why.
    ~Stage() = default;

private:
    StageSink& sink_;
    std::string name_;
    Clock::time_point start_;
};

// The scan as the octree sees it: the material at a point (a label lookup for
// label maps, the sign of the field for intensity) and each material's field.
class SelectionDomain : public octree::Domain {
public:
    SelectionDomain(std::shared_ptr<const imaging::Volume> v, std::shared_ptr<const imaging::Selection> s)
        : volume_(std::move(v)), selection_(std::move(s)) {
        for (std::size_t i = 0; i < selection_->materials.size(); ++i) slot_[selection_->materials[i].id] = i;
        // A flag per label from the smallest selected id to the largest, for
        // the per-voxel "is this label selected" of unionValue and labelAt
        // (8 map lookups per call were 7% of a label mesh's time).
        if (!slot_.empty()) {
            const std::int64_t lo = slot_.begin()->first, hi = slot_.rbegin()->first;
            if (hi - lo < (std::int64_t{1} << 20)) {
                firstLabel_ = static_cast<std::int32_t>(lo);
                selectedFlag_.assign(static_cast<std::size_t>(hi - lo + 1), 0);
                for (const auto& [id, i] : slot_) selectedFlag_[static_cast<std::size_t>(id - lo)] = 1;
            }
        }
    }
    std::int32_t materialAt(const Vec3& x) const override {
        if (volume_->kind == imaging::VolumeKind::Labels) return labelAt(x);
        const auto& m = selection_->materials.front();
        return m.field.value(x) < 0 ? m.id : 0;
    }
    double value(std::int32_t material, const Vec3& x, Vec3* gradient) const override {
        const imaging::ImplicitField& f = field(material);
        if (!gradient) return f.value(x);
        return f.valueAndGradient(x, *gradient);
    }
    // Intensity: the one material's field. Labels: 0.5 minus the trilinear
    // interpolation of the indicator of "any selected label" (the union's own
    // 0.5-isosurface, the reference fidelity() and the tests use for the
    // labelled region's volume).
    double unionValue(const Vec3& x, Vec3* gradient) const override {
        if (volume_->kind != imaging::VolumeKind::Labels) return value(selection_->materials.front().id, x, gradient);
        const auto [c0, t] = voxelCell(x);
        openvdb::tree::ValueAccessor<const openvdb::Int32Tree, false> acc(volume_->labels->tree());
        double in = 0;
        openvdb::Vec3d d(0, 0, 0);  // derivative of `in` in index space
        for (int c = 0; c < 8; ++c) {
            const int o[3] = {c & 1, c >> 1 & 1, c >> 2 & 1};
            if (!isSelected(acc.getValue(c0.offsetBy(o[0], o[1], o[2])))) continue;
            double w[3], dw[3];
            for (int a = 0; a < 3; ++a) {
                w[a] = o[a] ? t[a] : 1.0 - t[a];
                dw[a] = o[a] ? 1.0 : -1.0;
            }
            in += w[0] * w[1] * w[2];
            d[0] += dw[0] * w[1] * w[2];
            d[1] += w[0] * dw[1] * w[2];
            d[2] += w[0] * w[1] * dw[2];
        }
        if (gradient) {
            const openvdb::Vec3d gw = volume_->labels->transform().baseMap()->applyIJT(-d);
            *gradient = {gw[0], gw[1], gw[2]};
        }
        return 0.5 - in;
    }
    std::int32_t materialOtherThan(std::int32_t material, const Vec3& x) const override {
        std::int32_t best = 0;
        double bestValue = 0;
        for (const auto& m : selection_->materials) {
            if (m.id == material) continue;
            const double v = m.field.value(x);
            if (v < bestValue) {
                bestValue = v;
                best = m.id;
            }
        }
        return best;
    }
    const imaging::ImplicitField& field(std::int32_t material) const {
        // the octree asks for every sample: skip the map for a single material
        if (selection_->materials.size() == 1 && selection_->materials.front().id == material)
            return selection_->materials.front().field;
        const auto it = slot_.find(material);
        if (it == slot_.end()) throw Error("internal: no field for material " + std::to_string(material));
        return selection_->materials[it->second].field;
    }

private:
    // The voxel cell of the label grid that holds x: the index of its lower
    // corner voxel and x's position in it, each coordinate in [0, 1) (the
    // trilinear weights of the 8 voxels around x).
    struct VoxelCell {
        openvdb::Coord lower;
        openvdb::Vec3d t;
    };
    VoxelCell voxelCell(const Vec3& x) const {
        const openvdb::Vec3d u = volume_->labels->transform().worldToIndex(openvdb::Vec3d(x[0], x[1], x[2]));
        const openvdb::Coord c0(static_cast<int>(std::floor(u[0])), static_cast<int>(std::floor(u[1])),
                                static_cast<int>(std::floor(u[2])));
        return {c0, u - c0.asVec3d()};
    }

    // The label whose trilinear indicator weight at x is largest (unselected
    // labels count as background), the nearest voxel's label among equals.
    // At a voxel centre that is the voxel's own label; between voxels it
    // agrees with the fields (0.5 minus the indicator), so every grid edge
    // between two materials has the surface between them on it (or at an
    // end). The nearest voxel alone can disagree: at a corner shared by eight
    // voxels it picks one of them even where most of the eight are another
    // label, and the edges from there had no crossing.
    std::int32_t labelAt(const Vec3& x) const {
        const auto [c0, t] = voxelCell(x);
        openvdb::tree::ValueAccessor<const openvdb::Int32Tree, false> acc(volume_->labels->tree());
        auto selected = [&](std::int32_t label) { return isSelected(label) ? label : 0; };
        std::array<std::int32_t, 8> label{};
        std::array<double, 8> weight{};
        int n = 0;
        for (int c = 0; c < 8; ++c) {
            const int o[3] = {c & 1, c >> 1 & 1, c >> 2 & 1};
            const double w = (o[0] ? t[0] : 1.0 - t[0]) * (o[1] ? t[1] : 1.0 - t[1]) * (o[2] ? t[2] : 1.0 - t[2]);
            const std::int32_t l = selected(acc.getValue(c0.offsetBy(o[0], o[1], o[2])));
            int s = 0;
            while (s < n && label[s] != l) ++s;
            if (s == n) {
                label[n] = l;
                weight[n++] = 0;
            }
            weight[s] += w;
        }
        const std::int32_t nearest = selected(
            acc.getValue(volume_->labels->transform().worldToIndexCellCentered(openvdb::Vec3d(x[0], x[1], x[2]))));
        int best = 0;
        for (int s = 1; s < n; ++s)
            if (weight[s] > weight[best] || (weight[s] == weight[best] && label[s] == nearest)) best = s;
        return label[best];
    }

    std::shared_ptr<const imaging::Volume> volume_;
    std::shared_ptr<const imaging::Selection> selection_;
    bool isSelected(std::int32_t label) const {
        if (selectedFlag_.empty()) return slot_.count(label) != 0;
        const std::int64_t i = std::int64_t{label} - firstLabel_;
        return i >= 0 && i < static_cast<std::int64_t>(selectedFlag_.size()) && selectedFlag_[static_cast<std::size_t>(i)];
    }

    std::map<std::int32_t, std::size_t> slot_;
    std::int32_t firstLabel_ = 0;
    std::vector<std::uint8_t> selectedFlag_;  // empty: ids too far apart, use slot_
};

// Keeps surface nodes on their isosurface: the zero set of the inside
// material's field against the exterior, of f_a - f_b between two materials.
class FieldProjector : public smoothing::SurfaceProjector {
public:
    // With `repaired` (the extraction's RepairedDomain), points in cells around
    // a grid point the repair changed go onto its zero set, the surface the
    // mesh was extracted on there.
    FieldProjector(const SelectionDomain& d, const HexMesh& mesh, const octree::RepairedDomain* repaired = nullptr)
        : domain_(d), surfaces_(mesh.surfaces), curves_(mesh.curves), repaired_(repaired) {}
    Vec3 project(std::int32_t surfaceId, const Vec3& x) const override {
        const SurfaceTag& s = surfaces_.at(static_cast<std::size_t>(surfaceId));
        const std::int32_t a = s.inside, b = s.outside;
        if (repaired_ && (a > 0 || b > 0) && repaired_->nearChange(x)) {
            const octree::Domain& r = *repaired_;
            return newtonOnto(
                [&](const Vec3& y, Vec3& g) {
                    Vec3 ga{0, 0, 0}, gb{0, 0, 0};
                    double f = 0;
                    if (a > 0) f += r.value(a, y, &ga);
                    if (b > 0) f -= r.value(b, y, &gb);
                    g = {ga[0] - gb[0], ga[1] - gb[1], ga[2] - gb[2]};
                    return f;
                },
                x, domain_.field(a > 0 ? a : b).voxelSize());
        }
        if (a > 0 && b <= 0) return nearby(domain_.field(a), x);
        if (a <= 0 && b > 0) return nearby(domain_.field(b), x);
        if (a <= 0 && b <= 0) return x;  // the box around a meshed exterior: stays put
        return projectDifference(a, b, x);
    }

    // The box around a meshed exterior is no isosurface: project() leaves
    // its nodes where they are.
    bool projectsOnto(std::int32_t surfaceId) const override {
        const SurfaceTag& s = surfaces_.at(static_cast<std::size_t>(surfaceId));
        return s.inside > 0 || s.outside > 0;
    }

    // Curves where three materials meet (HexMesh::curves): where all three
    // are materials, f_p = f_q = f_r (the crossing of their interfaces, as
    // project() has them); against the outside, the union's isosurface
    // (where extraction put the vertices of such cells) crossed with the
    // interface of the other two.
    bool hasCurves() const override { return !curves_.empty(); }
    Vec3 projectToCurve(std::int32_t curveId, const Vec3& x0) const override {
        const double nan = std::numeric_limits<double>::quiet_NaN();
        if (curveId < 0 || static_cast<std::size_t>(curveId) >= curves_.size()) return {nan, nan, nan};
        const auto [p, q, r] = curves_[static_cast<std::size_t>(curveId)];
        const bool outer = p <= 0;
        const imaging::ImplicitField& fq = domain_.field(q);
        const imaging::ImplicitField& fr = domain_.field(r);
        const double voxel = fq.voxelSize();
        // the two functions whose common zero set is the curve, with gradients
        auto F = [&](const Vec3& y, Eigen::Matrix<double, 2, 3>& J) {
            Vec3 gq, gr, g0;
            const double vq = fq.valueAndGradient(y, gq), vr = fr.valueAndGradient(y, gr);
            double v0;
            if (outer) {
                v0 = domain_.unionValue(y, &g0);
            } else {
                v0 = domain_.field(p).valueAndGradient(y, g0);
                v0 -= vq;
                g0 = {g0[0] - gq[0], g0[1] - gq[1], g0[2] - gq[2]};
            }
            for (int c = 0; c < 3; ++c) {
                J(0, c) = gq[c] - gr[c];
                J(1, c) = g0[c];
            }
            return Eigen::Vector2d(vq - vr, v0);
        };
        // Levenberg-Marquardt onto both zero sets (damped least-norm steps,
        // which also get through places where one function is flat and the
        // two gradients agree), each step at most half a voxel; NaN where it
        // does not end within 1e-3 voxels of both or more than 3 voxels away.
        Eigen::Vector3d x(x0[0], x0[1], x0[2]);
        Eigen::Matrix<double, 2, 3> J;
        Eigen::Vector2d f;
        bool settled = false;
        for (int it = 0; it < 40 && !settled; ++it) {
            f = F(Vec3{x[0], x[1], x[2]}, J);
            if (!f.allFinite() || !J.allFinite()) return {nan, nan, nan};
            Eigen::Matrix2d JJ = J * J.transpose();
            const double damping = 1e-6 * JJ.trace() + 1e-300;
            JJ.diagonal().array() += damping;
            Eigen::Vector3d step = J.transpose() * JJ.ldlt().solve(f);
            if (!step.allFinite()) return {nan, nan, nan};
            settled = step.norm() < 1e-6 * voxel;
            if (step.norm() > 0.5 * voxel) step *= 0.5 * voxel / step.norm();
            x -= step;
        }
        f = F(Vec3{x[0], x[1], x[2]}, J);
        for (int i = 0; i < 2; ++i)
            if (!(std::abs(f[i]) <= 1e-3 * voxel * J.row(i).norm())) return {nan, nan, nan};
        if ((x - Eigen::Vector3d(x0[0], x0[1], x0[2])).norm() > 3.0 * voxel) return {nan, nan, nan};
        return {x[0], x[1], x[2]};
    }

private:
    // The smoother only asks for points near the surface (a node moved a
    // fraction of an element along it), so a projection that has to travel
    // more than a few voxels has found the wrong place, typically where the
    // field is flat far from any surface. Answer with a non-finite point: the
    // smoother rejects such a move (otherwise an untangling step could carry a
    // surface node far off the surface, as seen on the skull CT without sheet).
    static Vec3 nearby(const imaging::ImplicitField& f, const Vec3& x) {
        imaging::ProjectOptions o;
        o.maxDistanceVoxels = 3.0;
        const imaging::Projection p = f.projectDetailed(x, o);
        if (p.converged) return p.point;
        const double nan = std::numeric_limits<double>::quiet_NaN();
        return {nan, nan, nan};
    }
    // Newton steps on F = f_a - f_b along its gradient, each at most half a
    // voxel, keeping the best point; enough for the small moves of smoothing.
    Vec3 projectDifference(std::int32_t a, std::int32_t b, const Vec3& x0) const {
        const imaging::ImplicitField& fa = domain_.field(a);
        const imaging::ImplicitField& fb = domain_.field(b);
        return newtonOnto(
            [&](const Vec3& y, Vec3& g) {
                Vec3 ga, gb;
                const double F = fa.valueAndGradient(y, ga) - fb.valueAndGradient(y, gb);
                g = {ga[0] - gb[0], ga[1] - gb[1], ga[2] - gb[2]};
                return F;
            },
            x0, fa.voxelSize());
    }
    // Newton steps on F (value and gradient) along its gradient, each at most
    // half a voxel, keeping the best point; NaN beyond 3 voxels (see nearby()).
    template <class Fn>
    static Vec3 newtonOnto(const Fn& F, const Vec3& x0, double voxel) {
        const double maxStep = 0.5 * voxel;
        Vec3 x = x0, best = x0;
        double bestAbs = std::numeric_limits<double>::infinity(), bestGrad = 0;
        for (int it = 0; it < 30; ++it) {
            Vec3 g;
            const double f = F(x, g);
            const double g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
            if (std::abs(f) < bestAbs) {
                bestAbs = std::abs(f);
                bestGrad = std::sqrt(g2);
                best = x;
            }
            if (!(g2 > 0)) break;
            double step = f / std::sqrt(g2);
            if (std::abs(step) < 1e-6 * voxel) break;
            step = std::clamp(step, -maxStep, maxStep);
            const double inv = 1.0 / std::sqrt(g2);
            for (int c = 0; c < 3; ++c) x[c] -= step * g[c] * inv;
        }
        const double moved = std::sqrt((best[0] - x0[0]) * (best[0] - x0[0]) + (best[1] - x0[1]) * (best[1] - x0[1]) +
                                       (best[2] - x0[2]) * (best[2] - x0[2]));
        // Off the zero set (first-order distance |F|/|grad F| above 1e-3
        // voxel): Newton stopped where F is flat, or ran out of steps.
        if (moved > 3.0 * voxel || !(bestAbs <= 1e-3 * voxel * bestGrad)) {
            const double nan = std::numeric_limits<double>::quiet_NaN();
            return {nan, nan, nan};
        }
        return best;
    }
    const SelectionDomain& domain_;
    std::vector<SurfaceTag> surfaces_;
    std::vector<std::array<std::int32_t, 3>> curves_;
    const octree::RepairedDomain* repaired_ = nullptr;

};

bool isSurfaceFile(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    return ext == ".stl" || ext == ".obj" || ext == ".ply" || ext == ".off";
}

double meanEdgeLength(const imaging::TriangleSurface& s) {
    double sum = 0;
    std::size_t n = 0;
    for (const auto& t : s.triangles)
        for (int i = 0; i < 3; ++i) {
            const Vec3& a = s.vertices[t[i]];
            const Vec3& b = s.vertices[t[(i + 1) % 3]];
            sum += std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
            ++n;
        }
    if (n == 0) throw Error(s.source + ": the surface has no triangles");
    return sum / static_cast<double>(n);
}

// Index-space box of the voxels inside any selected material.
openvdb::CoordBBox solidBox(const imaging::Volume& vol, const imaging::Selection& sel) {
    const openvdb::CoordBBox box = vol.box;
    const int z0 = box.min().z(), z1 = box.max().z();
    auto join = [](openvdb::CoordBBox a, const openvdb::CoordBBox& b) {
        if (b.empty()) return a;
        if (a.empty()) return b;
        a.expand(b);
        return a;
    };
    return tbb::parallel_reduce(
        tbb::blocked_range<int>(z0, z1 + 1), openvdb::CoordBBox(),
        [&](const tbb::blocked_range<int>& r, openvdb::CoordBBox acc) {
            for (int k = r.begin(); k != r.end(); ++k)
                for (int j = box.min().y(); j <= box.max().y(); ++j)
                    for (int i = box.min().x(); i <= box.max().x(); ++i) {
                        const openvdb::Coord c(i, j, k);
                        bool in = false;
                        if (vol.kind == imaging::VolumeKind::Labels) {
                            const std::int32_t l = vol.labels->tree().getValue(c);
                            for (const auto& m : sel.materials) in = in || m.id == l;
                        } else {
                            in = sel.materials.front().field.grid().tree().getValue(c) < 0;
                        }
                        if (in) acc.expand(c);
                    }
            return acc;
        },
        join);
}

octree::Grid gridFor(const imaging::Volume& vol, const openvdb::CoordBBox& solid, const std::array<double, 3>& step,
                     int pad) {
    const openvdb::math::Transform& xf = vol.transform();
    const openvdb::Vec3d o = xf.indexToWorld(openvdb::Vec3d(0, 0, 0));
    octree::Grid g;
    openvdb::Vec3d start;
    for (int a = 0; a < 3; ++a) {
        openvdb::Vec3d e(0, 0, 0);
        e[a] = step[a];
        const openvdb::Vec3d w = xf.indexToWorld(e) - o;
        g.axes[a] = {w[0], w[1], w[2]};
        const double extent = solid.max()[a] - solid.min()[a];
        g.dims[a] = static_cast<int>(std::ceil(extent / step[a] - 1e-9)) + 1 + 2 * pad;
        start[a] = solid.min()[a] - pad * step[a];
    }
    const openvdb::Vec3d w0 = xf.indexToWorld(start);
    g.origin = {w0[0], w0[1], w0[2]};
    return g;
}

// The parts of every material that OpenVDB's volumeToMesh keeps apart, as
// one id per grid point (for the non-manifold repair): points of a material
// are in one part when 6-adjacent or on the inner side of one connected
// component of the volumeToMesh surface of the material's points (grid
// points of the material inside, the rest outside). Each surface polygon is
// dual to the grid edge it crosses, which names the point on its inner side.
// surfaces (optional): each material's components and Euler characteristic
// of that surface (what --isosurface-topology aims at).
std::vector<std::int32_t> marchingCubesRegions(const octree::Labels& l,
                                               std::vector<octree::RegionTopology>* surfaces = nullptr) {
    const octree::Grid& g = l.grid;
    const auto [nx, ny, nz] = g.dims;
    const std::size_t n = l.material.size();
    DisjointSets<std::int32_t> parts(n);
    auto unite = [&](std::size_t a, std::size_t b) {
        parts.unite(static_cast<std::int32_t>(a), static_cast<std::int32_t>(b));
    };
    std::map<std::int32_t, openvdb::CoordBBox> boxes;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t p = g.index(i, j, k);
                const std::int32_t m = l.material[p];
                if (m == 0) continue;
                boxes[m].expand(openvdb::Coord(i, j, k));
                if (i + 1 < nx && l.material[g.index(i + 1, j, k)] == m) unite(p, g.index(i + 1, j, k));
                if (j + 1 < ny && l.material[g.index(i, j + 1, k)] == m) unite(p, g.index(i, j + 1, k));
                if (k + 1 < nz && l.material[g.index(i, j, k + 1)] == m) unite(p, g.index(i, j, k + 1));
            }
    for (auto& [m, box] : boxes) {
        box.expand(1);
        auto grid = openvdb::FloatGrid::create(1.0f);
        auto acc = grid->getAccessor();
        for (int k = std::max(box.min().z(), 0); k <= std::min(box.max().z(), nz - 1); ++k)
            for (int j = std::max(box.min().y(), 0); j <= std::min(box.max().y(), ny - 1); ++j)
                for (int i = std::max(box.min().x(), 0); i <= std::min(box.max().x(), nx - 1); ++i)
                    if (l.material[g.index(i, j, k)] == m) acc.setValue(openvdb::Coord(i, j, k), -1.0f);
        std::vector<openvdb::Vec3s> pts;
        std::vector<openvdb::Vec3I> tris;
        std::vector<openvdb::Vec4I> quads;
        openvdb::tools::volumeToMesh(*grid, pts, tris, quads, 0.0);
        // surface components over the polygons' vertices
        DisjointSets<std::uint32_t> surface(pts.size());
        for (const auto& q : quads)
            for (int e = 0; e < 4; ++e) surface.unite(q[e], q[(e + 1) % 4]);
        for (const auto& t : tris)
            for (int e = 0; e < 3; ++e) surface.unite(t[e], t[(e + 1) % 3]);
        if (surfaces) {
            octree::RegionTopology t;
            t.material = m;
            std::vector<std::uint64_t> edges;
            auto edge = [&](std::uint32_t a, std::uint32_t b) {
                edges.push_back(static_cast<std::uint64_t>(std::min(a, b)) << 32 | std::max(a, b));
            };
            for (const auto& q : quads)
                for (int e = 0; e < 4; ++e) edge(q[e], q[(e + 1) % 4]);
            for (const auto& tr : tris)
                for (int e = 0; e < 3; ++e) edge(tr[e], tr[(e + 1) % 3]);
            std::sort(edges.begin(), edges.end());
            const auto e = static_cast<long long>(std::unique(edges.begin(), edges.end()) - edges.begin());
            std::vector<char> used(pts.size(), 0);
            for (const auto& q : quads)
                for (int k = 0; k < 4; ++k) used[q[k]] = 1;
            for (const auto& tr : tris)
                for (int k = 0; k < 3; ++k) used[tr[k]] = 1;
            long long v = 0;
            for (std::uint32_t a = 0; a < pts.size(); ++a) {
                if (!used[a]) continue;
                ++v;
                t.components += surface.find(a) == a;
            }
            t.euler = v - e + static_cast<long long>(quads.size() + tris.size());
            surfaces->push_back(t);
        }
        std::vector<std::int64_t> inner(pts.size(), -1);  // per surface component: a point on its inner side
        for (const auto& q : quads) {
            // the 4 vertices lie in the 4 cells around the crossed edge: equal
            // cell coordinate along the edge, the edge's start the largest of
            // the others
            int c[4][3];
            for (int e = 0; e < 4; ++e)
                for (int a = 0; a < 3; ++a) c[e][a] = static_cast<int>(std::floor(pts[q[e]][a]));
            int axis = -1;
            for (int a = 0; a < 3; ++a)
                if (c[0][a] == c[1][a] && c[0][a] == c[2][a] && c[0][a] == c[3][a]) axis = a;
            if (axis < 0) continue;
            int s[3];
            for (int a = 0; a < 3; ++a) s[a] = std::max(std::max(c[0][a], c[1][a]), std::max(c[2][a], c[3][a]));
            int t[3] = {s[0], s[1], s[2]};
            ++t[axis];
            if (s[0] < 0 || s[1] < 0 || s[2] < 0 || t[0] >= nx || t[1] >= ny || t[2] >= nz) continue;
            const std::size_t a = g.index(s[0], s[1], s[2]), b = g.index(t[0], t[1], t[2]);
            if ((l.material[a] == m) == (l.material[b] == m)) continue;
            const std::size_t in = l.material[a] == m ? a : b;
            const std::uint32_t comp = surface.find(q[0]);
            if (inner[comp] < 0) inner[comp] = static_cast<std::int64_t>(in);
            else unite(in, static_cast<std::size_t>(inner[comp]));
        }
    }
    std::vector<std::int32_t> id(n, -1);
    for (std::size_t p = 0; p < n; ++p)
        if (l.material[p] != 0) id[p] = parts.find(static_cast<std::int32_t>(p));
    return id;
}

// Hexes with a corner or centre Jacobian determinant <= 0, by index.
std::vector<Index> invertedHexes(const HexMesh& mesh) {
    const std::size_t H = mesh.hexCount();
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, H, 1 << 14), std::vector<Index>{},
        [&](const tbb::blocked_range<std::size_t>& range, std::vector<Index> l) {
            for (std::size_t h = range.begin(); h != range.end(); ++h)
                if (!(minJacobianDeterminant(hexCoords(mesh, static_cast<Index>(h))) > 0))
                    l.push_back(static_cast<Index>(h));
            return l;
        },
        [](std::vector<Index> a, const std::vector<Index>& b) {
            a.insert(a.end(), b.begin(), b.end());
            std::sort(a.begin(), a.end());
            return a;
        });
}

// What the grid-edit retries work on: the inverted hexes (by index) and the
// flat ones, not inverted with a scaled Jacobian below the floor (or
// degenerate: an edge of zero length), worst first.
struct Stuck {
    std::vector<Index> inverted;
    std::vector<Index> flat;
    double min = std::numeric_limits<double>::infinity();         // over all hexes
    double minValid = std::numeric_limits<double>::infinity();    // over the hexes not inverted
    // Fewer inverted; or as many and, with a floor, fewer flat with a minimum
    // over the rest no lower, or as many flat with a higher one.
    bool betterThan(const Stuck& o, double floor) const {
        if (inverted.size() != o.inverted.size()) return inverted.size() < o.inverted.size();
        if (!(floor > 0)) return false;
        if (flat.size() != o.flat.size()) return flat.size() < o.flat.size() && minValid >= o.minValid;
        return minValid > o.minValid;
    }
    nlohmann::json counts() const {
        return {{"inverted", inverted.size()}, {"flat", flat.size()}, {"min_scaled_jacobian", min},
                {"min_not_inverted", minValid}};
    }
};

Stuck stuckHexes(const HexMesh& mesh, double floor) {
    Stuck s;
    s.inverted = invertedHexes(mesh);
    const std::vector<double> sj = scaledJacobians(mesh);
    std::vector<char> inv(sj.size(), 0);
    for (Index h : s.inverted) inv[static_cast<std::size_t>(h)] = 1;
    std::vector<std::pair<double, Index>> low;
    for (std::size_t h = 0; h < sj.size(); ++h) {
        // scaledJacobian's value above 1 marks a degenerate hex: as flat as can be
        const double v = sj[h] > 1 ? 0.0 : sj[h];
        s.min = std::min(s.min, v);
        if (inv[h]) continue;
        s.minValid = std::min(s.minValid, v);
        if (v < floor) low.emplace_back(v, static_cast<Index>(h));
    }
    std::sort(low.begin(), low.end());
    for (const auto& [v, h] : low) s.flat.push_back(h);
    return s;
}

std::string shortNumber(double v) {
    std::ostringstream o;
    o << v;
    return o.str();
}

Vec3 hexCentre(const HexMesh& mesh, Index h) {
    Vec3 c{0, 0, 0};
    for (const Vec3& x : hexCoords(mesh, h))
        for (int i = 0; i < 3; ++i) c[i] += x[i] / 8.0;
    return c;
}

// The warning for hexes still inverted at the end (none: no warning);
// returns its text (empty when none) for the report.
std::string warnInverted(StageSink& sink, const HexMesh& mesh, const std::vector<Index>& left,
                         std::size_t afterUntangling, const std::string& more, bool fixedBoundary,
                         bool byCompare = false) {
    if (left.empty()) return {};
    const Vec3 c = hexCentre(mesh, left.front());
    std::string msg = std::to_string(left.size()) + " hex(es) stay inverted after optimisation";
    if (left.size() != afterUntangling) msg += " (" + std::to_string(afterUntangling) + " after untangling)";
    msg += "; first at (" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " + std::to_string(c[2]) + ")" +
           more +
           (!fixedBoundary ? "; another --size may avoid them"
            : byCompare ? "; compare keeps every surface node where extraction put it (the seed's protocol), and hexes "
                          "on a folded surface can only be untangled by moving those: --move-boundary lets them move"
                        : "; --fix-boundary keeps every surface node where extraction put it, and hexes on a folded "
                          "surface can only be untangled by moving those: drop it, or try another --size");
    sink.note("warning", msg);
    return msg;
}

// The report's grid.topology: components and Euler characteristic per material.
nlohmann::json topologyJson(const std::vector<octree::RegionTopology>& topo) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& t : topo)
        out.push_back({{"material", t.material}, {"components", t.components}, {"euler", t.euler},
                       {"genus_total", static_cast<long long>(t.components) - t.euler / 2}});
    return out;
}

// The mesh's size before any of it is built. A --size far below the voxel
// spacing (the sphere phantom at 0.1 made 34.5 M hexes and a 4 GB file in
// 400 s) would otherwise run until the machine runs out of memory. The hex
// count is the selected volume over the element volume (the whole grid with
// --mesh-exterior), plus a sixth for the sheet. Each hex costs about 420
// bytes at peak on top of what is already in memory (the sphere phantom's
// `peak_memory_mb` at --size 0.5 and 0.25: 242 and 1045 MB for 0.30 and
// 2.28 M hexes); the estimate takes 450 and adds the process's peak so far.
void checkMeshMemory(const std::string& input, const imaging::Volume& vol, const imaging::Selection& sel,
                     const octree::Grid& g, const MeshSettings& settings) {
    const auto sp = g.spacing();
    const double element = sp[0] * sp[1] * sp[2];
    const double voxel = vol.spacing[0] * vol.spacing[1] * vol.spacing[2];
    double voxels = 0;
    for (const auto& m : sel.materials) voxels += double(m.voxels);
    double hexes = voxels * voxel / element;
    if (settings.meshExterior) hexes = double(g.size());
    if (settings.pillow) hexes *= 7.0 / 6.0;
    constexpr double bytesPerHex = 450.0;
    struct rusage ru {};
    getrusage(RUSAGE_SELF, &ru);
    const double already = double(ru.ru_maxrss) * 1024.0;
    const double need = already + hexes * bytesPerHex + double(g.size()) * 8.0;
    double budget = settings.load.maxMemoryMB * 1024.0 * 1024.0;
    std::string what = "the --max-memory budget";
    if (!(settings.load.maxMemoryMB > 0.0)) {
        budget = 0.8 * double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
        what = "80% of this machine's memory";
    }
    if (need <= budget) return;
    // the element size that would fit, in steps of the usual knob
    // The element size whose mesh would fit, rounded up to two digits (none
    // when what is loaded already takes most of the budget).
    std::string fitting;
    if (already < 0.9 * budget) {
        double fit = std::cbrt((need - already) / (budget - already)) * std::cbrt(element);
        const double unit = std::pow(10.0, std::floor(std::log10(fit)) - 1);
        fitting = "Use a --size of at least " + shortNumber(std::ceil(fit / unit) * unit) + ", or raise";
    } else {
        std::ostringstream a;
        a.precision(3);
        a << "The input alone takes " << already / double(1 << 30) << " GiB; raise";
        fitting = a.str();
    }
    std::ostringstream m;
    m.precision(3);
    m << input << ": at this element size (" << shortNumber(sp[0]) << " x " << shortNumber(sp[1]) << " x "
      << shortNumber(sp[2]) << " world units; the input's voxels are " << shortNumber(vol.spacing[0]) << " x "
      << shortNumber(vol.spacing[1]) << " x " << shortNumber(vol.spacing[2]) << ") the mesh would have about "
      << hexes / 1e6 << " million hexes and need about " << need / double(1 << 30) << " GiB (estimate), more than "
      << what << " (" << budget / double(1 << 30) << " GiB). " << fitting
      << " --max-memory if the machine has the memory.";
    throw Error(m.str());
}

nlohmann::json gridJson(const octree::Grid& g) {
    const auto s = g.spacing();
    return {{"dims", g.dims}, {"spacing", s}, {"origin", g.origin}, {"points", g.size()}};
}

}  // namespace

// OpenVDB's own marching-cubes cell tables, for the repair's exact topology test.
const octree::CellEdgeGroups& volumeToMeshTables() {
    static const octree::CellEdgeGroups table = [] {
        octree::CellEdgeGroups t;
        for (int p = 0; p < 256; ++p) {
            for (int e = 0; e < 13; ++e) t.edgeGroups[p][e] = openvdb::tools::volume_to_mesh_internal::sEdgeGroupTable[p][e];
            t.ambiguousFace[p] = openvdb::tools::volume_to_mesh_internal::sAmbiguousFace[p];
        }
        return t;
    }();
    return table;
}

Prepared prepare(const std::string& input, const MeshSettings& settings, StageSink& sink) {
    Prepared p;
    if (settings.size && settings.level)
        throw Error("--size and --level both given; choose one (--size is the element edge length in world units)");
    if (settings.size && !(*settings.size > 0))
        throw Error("--size must be a positive length in world units (got " + std::to_string(*settings.size) + ")");
    std::optional<double> size = settings.size;
    nlohmann::json surfaceJson;
    std::optional<imaging::SurfaceTopology> surfaceTopo;  // a triangle surface's own topology
    {
        Stage st(sink, "load");
        if (isSurfaceFile(input)) {
            // A closed triangle surface becomes a signed-distance level set (two
            // voxels per element), meshed like a scan whose iso value is 0.
            imaging::TriangleSurface surface = imaging::loadSurface(input);
            imaging::checkClosedManifold(surface);
            if (!size) size = meanEdgeLength(surface);
            imaging::LevelSetOptions lso;
            lso.elementSize = *size;
            lso.maxMemoryMB = settings.load.maxMemoryMB;
            surfaceTopo = imaging::surfaceTopology(surface);
            surfaceJson = {{"triangles", surface.triangles.size()},
                           {"vertices", surface.vertices.size()},
                           {"volume", surface.volume()},
                           {"area", surface.area()},
                           {"flipped", surface.flipped},
                           {"components", surfaceTopo->components},
                           {"euler_characteristic", surfaceTopo->euler}};
            imaging::SurfaceLevelSet ls = imaging::surfaceToLevelSet(std::move(surface), lso);
            auto vol = std::make_shared<imaging::Volume>();
            vol->kind = imaging::VolumeKind::Intensity;
            vol->intensity = ls.grid;
            vol->box = ls.grid->evalActiveVoxelBoundingBox();
            vol->box.expand(2);
            vol->spacing = {ls.voxelSize, ls.voxelSize, ls.voxelSize};
            const openvdb::Vec3d o = ls.grid->transform().indexToWorld(openvdb::Vec3d(0, 0, 0));
            vol->origin = {o[0], o[1], o[2]};
            vol->minValue = -ls.grid->background();
            vol->maxValue = ls.grid->background();
            vol->levelSet = true;
            vol->source = input;
            vol->format = "triangle surface";
            vol->pixelType = "float32 (signed distance)";
            p.volume = vol;
        } else {
            imaging::LoadOptions lo = settings.load;
            lo.progress = [&](std::string_view, double f) { sink.progress(f); };
            lo.reading = [&](const std::string& file) { sink.reading(file); };
            p.volume = std::make_shared<const imaging::Volume>(imaging::loadVolume(input, lo));
        }
        st.finish();
    }
    const imaging::Volume& vol = *p.volume;
    {
        Stage st(sink, "select");
        imaging::SelectOptions so = settings.select;
        so.progress = [&](std::string_view, double f) { sink.progress(f); };
        p.selection = std::make_shared<const imaging::Selection>(imaging::select(vol, so));
        st.finish();
    }
    const imaging::Selection& sel = *p.selection;
    auto domain = std::make_shared<SelectionDomain>(p.volume, p.selection);
    p.domain = domain;

    nlohmann::json in;
    in["path"] = input;
    in["format"] = vol.format;
    in["pixel_type"] = vol.pixelType;
    in["kind"] = vol.kind == imaging::VolumeKind::Labels ? "labels" : "intensity";
    in["dimensions"] = {vol.dims().x(), vol.dims().y(), vol.dims().z()};
    in["spacing"] = vol.spacing;
    in["origin"] = vol.origin;
    in["direction"] = vol.direction;
    in["data_range"] = {vol.minValue, vol.maxValue};
    in["coordinates"] = "LPS (ITK physical space), world units of the scan (mm for medical images)";
    if (!vol.seriesUid.empty()) in["dicom_series"] = vol.seriesUid;
    if (!surfaceJson.is_null()) in["surface"] = surfaceJson;
    nlohmann::json selJson;
    if (sel.iso) {
        selJson["iso"] = *sel.iso;
        selJson["iso_from_otsu"] = sel.isoFromOtsu;
        selJson["inside"] = sel.insideBelow ? "below" : "above";
        if (sel.isoFromOtsu)
            sink.note("info", "iso value " + std::to_string(*sel.iso) + " chosen by Otsu's method (set it with --iso)");
    }
    for (const auto& m : sel.materials) selJson["materials"].push_back({{"id", m.id}, {"voxels", m.voxels}});
    for (const auto& d : sel.dropped) {
        selJson["dropped_labels"].push_back({{"label", d.label}, {"voxels", d.voxels}});
        p.warnings.push_back("label " + std::to_string(d.label) + " has only " + std::to_string(d.voxels) +
                             " voxels and was dropped (--min-label-voxels)");
    }
    p.report["input"] = in;
    p.report["selection"] = selJson;

    Stage st(sink, "octree");
    const openvdb::CoordBBox solid = solidBox(vol, sel);
    if (solid.empty()) throw Error(input + ": the selection contains no voxel; nothing to mesh");
    const int pad = settings.meshExterior ? 1 + settings.exteriorMargin : 2;
    const double spacingMin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
    octree::LevelChoice choice;
    std::array<double, 3> step{1, 1, 1};
    nlohmann::json grid;
    if (size) {
        for (int a = 0; a < 3; ++a) step[a] = *size / vol.spacing[a];
        if (*size < 0.5 * spacingMin)
            p.warnings.push_back("--size " + std::to_string(*size) +
                                 " is below half the voxel spacing; the mesh cannot resolve more than the scan");
        grid["chosen_by"] = "size";
    } else if (settings.level) {
        if (*settings.level < 0 || *settings.level > 10)
            throw Error("--level must be between 0 and 10 (got " + std::to_string(*settings.level) + ")");
        step.fill(static_cast<double>(1 << *settings.level));
        grid["chosen_by"] = "level";
    } else {
        const octree::Grid base = gridFor(vol, solid, step, pad);
        choice = octree::chooseLevel(*domain, base);
        step.fill(static_cast<double>(1 << choice.level));
        grid["chosen_by"] = "topology";
        grid["rejected"] = choice.notes;
    }
    const octree::Grid g = gridFor(vol, solid, step, pad);
    checkMeshMemory(input, vol, sel, g, settings);
    p.labels = octree::sampleLabels(*domain, g);
    const octree::Labels sampled = p.labels;
    if (settings.keepLargest) {
        const std::size_t removed = octree::keepLargestComponents(p.labels);
        grid["points_in_smaller_components_removed"] = removed;
        if (removed) sink.note("info", "kept the largest region of each material (" + std::to_string(removed) +
                                           " grid points of smaller regions removed)");
    }
    sink.progress(0.5);
    std::vector<octree::RegionTopology> isosurface;  // volumeToMesh's, for --isosurface-topology
    const std::vector<std::int32_t> regions =
        marchingCubesRegions(p.labels, settings.isosurfaceTopology ? &isosurface : nullptr);
    const auto repairStart = std::chrono::steady_clock::now();
    std::optional<octree::Labels> beforeRepair;
    if (settings.isosurfaceTopology) beforeRepair = p.labels;
    octree::RepairReport rep = octree::repairNonManifold(p.labels, *domain, &regions);
    std::optional<octree::TopologyMatchReport> match;
    if (beforeRepair) match = octree::matchPolygonTopology(p.labels, *beforeRepair, *domain, volumeToMeshTables());
    // Repair can cut a thin bridge; keep the largest region again and re-check
    // (not with --isosurface-topology: the pieces the isosurface has apart
    // stay, as there).
    if (settings.keepLargest && (!match || match->discarded) && octree::keepLargestComponents(p.labels) > 0) {
        const octree::RepairReport again = octree::repairNonManifold(p.labels, *domain);
        rep.pointsAdded += again.pointsAdded;
        rep.pointsRemoved += again.pointsRemoved;
        rep.rounds += again.rounds;
    }
    // One-cell pits go after the repair (which can open them) and before the
    // repaired field is built, so their new boundary gets a field too.
    std::size_t pitsFilled = 0;
    if (settings.fillPits && settings.method == "dual") {
        pitsFilled = octree::fillOneCellPits(p.labels);
        if (pitsFilled > 0) {
            const octree::RepairReport again = octree::repairNonManifold(p.labels, *domain);
            rep.pointsAdded += again.pointsAdded;
            rep.pointsRemoved += again.pointsRemoved;
            rep.rounds += again.rounds;
            sink.note("info", "filled " + std::to_string(pitsFilled) +
                                  " grid points of pits and wells one element wide (--fill-pits)");
        }
    }
    grid["pits_filled"] = pitsFilled;
    const double repairSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - repairStart).count();
    {
        auto repaired = std::make_shared<octree::RepairedDomain>(*domain, sampled, p.labels);
        grid["repaired_field_points"] = repaired->changedPoints();
        if (repaired->changedPoints() > 0) p.repairedDomain = std::move(repaired);
    }
    const auto topo = octree::regionTopology(p.labels);
    if (topo.empty()) {
        // Nothing left to mesh (an element larger than the object, or a level
        // that coarse): say so rather than hand an empty mesh to the optimiser.
        const auto sp = g.spacing();
        throw Error(input + ": no grid point lies inside the selected material(s) at this element size (" +
                    shortNumber(sp[0]) + " x " + shortNumber(sp[1]) + " x " + shortNumber(sp[2]) +
                    " world units), so there is nothing to mesh; use a smaller --size or a lower --level");
    }
    grid["step_voxels"] = step;
    grid["element_size"] = g.spacing();
    if (!size) grid["level"] = settings.level ? *settings.level : choice.level;
    grid["grid"] = gridJson(g);
    grid["repair"] = {{"nonmanifold_blocks_before", rep.nonManifoldBefore},
                      {"points_added", rep.pointsAdded},
                      {"points_removed", rep.pointsRemoved},
                      {"rounds", rep.rounds},
                      {"seconds", repairSeconds}};
    if (!topo.empty()) grid["topology"] = topologyJson(topo);
    if (match) {
        // what --isosurface-topology did and aimed at, and where it fell short
        nlohmann::json& block = grid["repair"]["isosurface_topology"];
        block = {{"groups", match->groups},
                 {"groups_changing_it", match->groupsChanging},
                 {"groups_mended", match->groupsMatched},
                 {"points_changed", match->pointsChanged},
                 {"deep_search_trials", match->deepTrials},
                 {"anneal_steps", match->annealSteps},
                 {"discarded", match->discarded},
                 {"isosurface", nlohmann::json::array()},
                 {"unmended", nlohmann::json::array()}};
        // where the search fell short, in world coordinates (the box of the
        // grid points the repair changed there) and on the grid
        std::string where;
        for (const auto& pl : match->unmended) {
            const Vec3 a = g.point(pl.lo[0], pl.lo[1], pl.lo[2]), b = g.point(pl.hi[0], pl.hi[1], pl.hi[2]);
            Vec3 lo, hi;
            for (int d = 0; d < 3; ++d) {
                lo[d] = std::min(a[d], b[d]);
                hi[d] = std::max(a[d], b[d]);
            }
            block["unmended"].push_back({{"world_min", lo},
                                         {"world_max", hi},
                                         {"grid_min", pl.lo},
                                         {"grid_max", pl.hi},
                                         {"points", pl.points},
                                         {"euler_change", pl.eulerChange}});
            if (block["unmended"].size() <= 3)
                where += std::string(where.empty() ? "" : ", ") + "(" + shortNumber(lo[0]) + ", " + shortNumber(lo[1]) +
                         ", " + shortNumber(lo[2]) + ")";
        }
        if (match->unmended.size() > 3) where += ", ...";
        nlohmann::json& out = block["isosurface"];
        for (const auto& want : isosurface) {
            out.push_back({{"material", want.material}, {"components", want.components}, {"euler", want.euler}});
            const auto it =
                std::find_if(topo.begin(), topo.end(), [&](const auto& t) { return t.material == want.material; });
            const std::size_t c = it == topo.end() ? 0 : it->components;
            const long long e = it == topo.end() ? 0 : it->euler;
            if (c == want.components && e == want.euler) continue;
            std::string why;
            if (match->discarded)
                why = "its result was not manifold and was dropped (please report this with the input)";
            else if (match->groupsMatched < match->groupsChanging)
                why = "the search mended " + std::to_string(match->groupsMatched) + " of the " +
                      std::to_string(match->groupsChanging) +
                      " places (all materials) where the repair changed the isosurface's topology" +
                      (where.empty() ? std::string() : "; not mended near " + where);
            else
                why = "every place the first repair changed was mended; a later step (--fill-pits and its repair) "
                      "changed it";
            p.warnings.push_back("material " + std::to_string(want.material) +
                                 ": --isosurface-topology: the mesh boundary has " + std::to_string(c) +
                                 " component(s), Euler characteristic " + std::to_string(e) +
                                 "; the isosurface on the element grid has " + std::to_string(want.components) +
                                 " component(s), Euler characteristic " + std::to_string(want.euler) + ". Why: " + why +
                                 " (grid.repair.isosurface_topology in the report)");
        }
    }
    // Compare with the topology the mesh should have. A triangle surface has
    // its own (its level set's voxels are half an element, so a voxel-level
    // reference would coarsen with --size and miss what a large size loses);
    // a scan is compared with the grid at voxel spacing, when the user forced
    // the grid.
    std::vector<octree::RegionTopology> ref;
    std::string refName;
    if (surfaceTopo) {
        octree::RegionTopology t;
        t.material = 1;
        t.components = surfaceTopo->components;
        t.euler = surfaceTopo->euler;
        ref.push_back(t);
        refName = "input surface";
    } else if ((size || settings.level) && vol.voxelCount() <= 60'000'000) {
        // At the voxel spacing the grid is the voxel grid itself: nothing to compare.
        const octree::Grid fineGrid = gridFor(vol, solid, {1, 1, 1}, 2);
        const bool same = fineGrid.dims == g.dims && fineGrid.origin == g.origin && fineGrid.axes == g.axes;
        ref = topo;
        if (!same) {
            octree::Labels fine = octree::sampleLabels(*domain, fineGrid);
            if (settings.keepLargest) octree::keepLargestComponents(fine);
            octree::repairNonManifold(fine, *domain);
            ref = octree::regionTopology(fine);
        }
        refName = "voxel resolution";
    }
    for (const auto& r : ref) {
        const auto it = std::find_if(topo.begin(), topo.end(), [&](const auto& t) { return t.material == r.material; });
        if (it == topo.end())
            p.warnings.push_back("material " + std::to_string(r.material) + " vanishes at this element size");
        else if (it->components != r.components || it->euler != r.euler)
            p.warnings.push_back("material " + std::to_string(r.material) + ": the element size changes the topology of its surface (" + refName + ": " +
                                 std::to_string(r.components) + " component(s), Euler characteristic " + std::to_string(r.euler) +
                                 "; this mesh: " + std::to_string(it->components) + " component(s), Euler characteristic " +
                                 std::to_string(it->euler) + ")" +
                                 (surfaceTopo ? "; tunnels, gaps or parts thinner than about an element are closed or dropped, a smaller --size keeps more of them" : ""));
    }
    if (rep.nonManifoldBefore > 0)
        sink.note("info", "repaired " + std::to_string(rep.nonManifoldBefore) + " non-manifold places (" +
                              std::to_string(rep.pointsAdded) + " grid points added, " + std::to_string(rep.pointsRemoved) +
                              " removed)");
    p.report["grid"] = grid;
    st.finish();
    for (const auto& w : p.warnings) sink.note("warning", w);
    return p;
}

HexMesh extract(const Prepared& p, const MeshSettings& settings, StageSink& sink) {
    Stage st(sink, "extract");
    octree::ExtractOptions opt;
    opt.meshExterior = settings.meshExterior;
    if (settings.method == "voxel") opt.cellCentres = true;
    else if (settings.method != "dual")
        throw Error("--method must be 'dual' or 'voxel' (got '" + settings.method + "')");
    octree::ExtractStats stats;
    HexMesh mesh = octree::dualContourHexes(p.labels, p.extractionDomain(), opt, &stats);
    // Starting the sheet's inner copies at the held-back positions with the
    // surface nodes on the surface was tried: the surface quads of those nodes
    // are folded, so the sheet hexes on them start inverted (skull CT: 8,860
    // inverted at insertion against 3,508, 7 left after optimisation against 0).
    for (std::size_t i = 0; i < stats.heldBack.size(); ++i)
        mesh.nodes[static_cast<std::size_t>(stats.heldBack[i])] = stats.heldBackAt[i];
    if (settings.meshExterior)  // the box around the exterior does not move
        for (std::size_t s = 0; s < mesh.surfaces.size(); ++s)
            if (mesh.surfaces[s].inside <= 0 && mesh.surfaces[s].outside <= 0)
                for (auto& c : mesh.nodeClass)
                    if (c.kind == NodeKind::Surface && c.id == static_cast<std::int32_t>(s)) c = {NodeKind::Fixed, -1};
    st.finish();
    return mesh;
}

nlohmann::json insertSheets(HexMesh& mesh, const MeshSettings& settings, StageSink& sink) {
    nlohmann::json j;
    j["enabled"] = settings.pillow;
    if (!settings.pillow) return j;
    Stage st(sink, "pillow");
    const std::size_t before = mesh.hexCount();
    PillowOptions opt;
    const auto results = pillowAllMaterials(mesh, settings.boundaryLayers, opt);
    j["layers"] = settings.boundaryLayers;
    j["sheets"] = results.size();
    j["hexes_added"] = mesh.hexCount() - before;
    std::size_t inverted = 0;
    for (const auto& r : results) inverted += r.invertedAtStart;
    j["inverted_at_insertion"] = inverted;
    st.finish();
    return j;
}

nlohmann::json optimize(HexMesh& mesh, const Prepared& p, const MeshSettings& settings, StageSink& sink,
                        bool warnLeftInverted) {
    nlohmann::json j;
    j["enabled"] = settings.optimize;
    if (!settings.optimize) return j;
    Stage st(sink, "optimize");
    smoothing::SmoothingOptions opt;
    opt.fixBoundary = settings.fixBoundary;
    const auto* domain = static_cast<const SelectionDomain*>(p.domain.get());
    FieldProjector projector(*domain, mesh, static_cast<const octree::RepairedDomain*>(p.repairedDomain.get()));
    // Smoothing moves nodes only: one topology serves the optimiser and the
    // worst-hex pass (building it is about a second at 1.9 M hexes).
    const Topology topo = buildTopology(mesh);
    const smoothing::SmoothingResult r =
        smoothing::optimizeMesh(mesh, settings.fixBoundary ? nullptr : &projector, opt,
                                [&](std::string_view, double f) { sink.progress(f); }, &topo);
    // The optimiser minimises a sum over all corners; the few hexes it leaves
    // poor (surface folds, spurs thinner than an element) get a max-min pass.
    if (settings.worstHexPass) {
        // The slack in world units: the tolerance is in voxels of the scan
        // (its smallest spacing), as the fidelity report measures.
        // (None with --fix-boundary: surface nodes do not move at all.)
        const double voxels =
            settings.fixBoundary ? 0.0 : settings.surfaceTolerance.value_or(kDefaultSurfaceTolerance);
        const double slack = voxels * p.selection->materials.front().field.voxelSize();
        j["worst_hexes"] =
            worstHexPass(mesh, settings.fixBoundary ? nullptr : &projector, settings.worstHexTarget, slack, &topo);
        j["worst_hexes"]["surface_tolerance_voxels"] = voxels;
    }
    j["fix_boundary"] = settings.fixBoundary;
    j["sweeps"] = r.sweeps;
    j["untangle_sweeps"] = r.untangleSweeps;
    j["nodes_moved"] = r.nodesMoved;
    j["node_updates"] = r.nodeUpdates;
    j["surface_nodes_off_surface"] = r.surfaceNodesReleased;
    j["curve_nodes_demoted"] = r.curveNodesDemoted;
    j["inverted_before"] = r.invertedBefore;
    j["inverted_after"] = r.invertedAfter;
    j["mean_inverse_mean_ratio_before"] = r.objectiveBefore;
    j["mean_inverse_mean_ratio_after"] = r.objectiveAfter;
    j["converged"] = r.converged;
    j["seconds"] = {{"setup", r.setupSeconds}, {"untangle", r.untangleSeconds},
                    {"mean_ratio", r.meanRatioSeconds}, {"total", r.seconds}};
    // The mean-ratio kernels' lanes (same numbers either way; only the time differs).
    j["instruction_set"] = smoothing::detail::imrInstructionSet();
    for (const auto& f : r.untangleFailures) {
        j["untangle_failures"].push_back({{"hex", f.hex}, {"at", f.centroid}, {"min_determinant", f.minDeterminant}});
        if (j["untangle_failures"].size() >= 20) break;
    }
    // The warning counts what is still inverted after the worst-hex pass too
    // (which may fix some, and may trade one for another), at the first.
    // (runMeshPipeline counts and warns itself, after its retries.)
    j["inverted_after_untangling"] = r.untangleFailures.size();
    if (warnLeftInverted && !r.untangleFailures.empty())
        warnInverted(sink, mesh, invertedHexes(mesh), r.untangleFailures.size(), "", settings.fixBoundary,
                     settings.fixBoundaryByCompare);
    st.finish();
    return j;
}

nlohmann::json worstHexPass(HexMesh& mesh, const smoothing::SurfaceProjector* projector, double target,
                            double slack, const Topology* topo) {
    const auto t0 = std::chrono::steady_clock::now();
    smoothing::WorstHexOptions wo;
    wo.target = target;
    wo.surfaceSlack = slack;
    const smoothing::WorstHexResult w = smoothing::raiseWorstHexes(mesh, projector, wo, topo);
    return {{"target", wo.target},
            {"min_edge", wo.minEdge},
            {"min_scaled_jacobian_before", w.minBefore},
            {"min_scaled_jacobian_after", w.minAfter},
            {"below_target_before", w.belowBefore},
            {"below_target_after", w.belowAfter},
            {"nodes_moved", w.nodesMoved},
            {"surface_nodes_released", w.surfaceNodesReleased},
            {"joint_regions_tried", w.jointRegionsTried},
            {"joint_regions_improved", w.jointRegionsImproved},
            {"joint_seconds", w.jointSeconds},
            {"mean_rounds", w.meanRounds},
            {"mean_gain", w.meanGain},
            {"mean_seconds", w.meanSeconds},
            {"surface_nodes_off_before_return", w.surfaceNodesOffBefore},
            {"surface_nodes_off_after_return", w.surfaceNodesOffAfter},
            {"surface_slack", wo.surfaceSlack},
            {"surface_nodes_within_slack", w.surfaceNodesWithinSlack},
            {"return_seconds", w.returnSeconds},
            {"rounds", w.rounds},
            {"seconds", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}};
}

double isosurfaceVolume(const openvdb::FloatGrid& grid) {
    std::vector<openvdb::Vec3s> pts;
    std::vector<openvdb::Vec3I> tris;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(grid, pts, tris, quads, 0.0);
    double v = 0;
    auto add = [&](const openvdb::Vec3s& a, const openvdb::Vec3s& b, const openvdb::Vec3s& c) {
        v += openvdb::Vec3d(a).dot(openvdb::Vec3d(b).cross(openvdb::Vec3d(c))) / 6.0;
    };
    for (const auto& t : tris) add(pts[t[0]], pts[t[1]], pts[t[2]]);
    for (const auto& q : quads) {
        add(pts[q[0]], pts[q[1]], pts[q[2]]);
        add(pts[q[0]], pts[q[2]], pts[q[3]]);
    }
    return std::abs(v);
}

openvdb::FloatGrid::Ptr labelUnionField(const imaging::Selection& selection) {
    // Each label's field is 0.5 minus its (possibly blurred) indicator, and
    // the labels are disjoint, so the union's indicator is the sum of theirs:
    // the union's field is 0.5 minus that sum. Values off a field's active
    // set are its background, 0.5 (indicator 0).
    if (selection.materials.empty()) throw Error("labelUnionField: no materials");
    auto out = openvdb::FloatGrid::create(0.5f);
    out->setTransform(selection.materials.front().field.grid().transform().copy());
    auto acc = out->getAccessor();
    for (const auto& m : selection.materials) {
        const openvdb::FloatGrid& g = m.field.grid();
        for (auto it = g.cbeginValueOn(); it; ++it) {
            const float in = 0.5f - *it;
            if (in == 0.0f) continue;
            if (it.isVoxelValue()) {
                acc.setValue(it.getCoord(), acc.getValue(it.getCoord()) - in);
            } else {
                openvdb::CoordBBox box;
                it.getBoundingBox(box);
                for (auto c = box.begin(); c; ++c) acc.setValue(*c, acc.getValue(*c) - in);
            }
        }
    }
    return out;
}

nlohmann::json fidelity(const HexMesh& mesh, const Prepared& p) {
    const auto* domain = static_cast<const SelectionDomain*>(p.domain.get());
    nlohmann::json j;
    // Volume the isosurface encloses, from OpenVDB's own polygonisation of the
    // field's zero set (divergence theorem over its polygons).
    double isoTotal = 0, meshTotal = 0, voxTotal = 0;
    const double voxelVolume = p.volume->spacing[0] * p.volume->spacing[1] * p.volume->spacing[2];
    std::map<std::int32_t, double> meshVolume;
    {
        // Volumes in parallel, summed in hex order: the same total for any thread count.
        std::vector<double> vol(mesh.hexCount());
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, vol.size(), 4096), [&](const auto& r) {
            for (std::size_t h = r.begin(); h != r.end(); ++h) vol[h] = hexVolume(hexCoords(mesh, static_cast<Index>(h)));
        });
        for (std::size_t h = 0; h < vol.size(); ++h) meshVolume[mesh.material[h]] += vol[h];
    }
    for (const auto& m : p.selection->materials) {
        const double v = isosurfaceVolume(m.field.grid());
        const double mv = meshVolume.count(m.id) ? meshVolume[m.id] : 0.0;
        isoTotal += v;
        meshTotal += mv;
        nlohmann::json mj = {{"material", m.id},
                             {"volume_mesh", mv},
                             {"volume_isosurface", v},
                             {"volume_change_percent", v > 0 ? 100.0 * (mv - v) / v : 0.0}};
        if (p.volume->kind == imaging::VolumeKind::Labels) {
            // A label's 0.5-isosurface rounds its voxels' corners off, so for thin
            // labels it encloses clearly less than the segmentation's own voxels;
            // report both references.
            const double vox = static_cast<double>(m.voxels) * voxelVolume;
            mj["volume_voxels"] = vox;
            mj["volume_change_vs_voxels_percent"] = vox > 0 ? 100.0 * (mv - vox) / vox : 0.0;
            voxTotal += vox;
        }
        j["materials"].push_back(mj);
    }
    // Several labels: the labels' own isosurfaces leave gaps where three
    // labels (or two and the outside) meet, so their sum falls short of the
    // labelled region (6% on the JHU atlas), while the mesh partitions it.
    // The total is compared with the union's 0.5-isosurface (the surface the
    // outer boundary is extracted on); the sum is reported beside it.
    if (p.volume->kind == imaging::VolumeKind::Labels && p.selection->materials.size() > 1) {
        j["volume_labels_isosurfaces"] = isoTotal;
        isoTotal = isosurfaceVolume(*labelUnionField(*p.selection));
        j["volume_isosurface_of"] = "union of the selected labels";
    } else {
        j["volume_isosurface_of"] = p.volume->kind == imaging::VolumeKind::Labels ? "label" : "field";
    }
    j["volume_mesh"] = meshTotal;
    j["volume_isosurface"] = isoTotal;
    j["volume_change_percent"] = isoTotal > 0 ? 100.0 * (meshTotal - isoTotal) / isoTotal : 0.0;
    if (voxTotal > 0) {
        j["volume_voxels"] = voxTotal;
        j["volume_change_vs_voxels_percent"] = 100.0 * (meshTotal - voxTotal) / voxTotal;
    }
    // Distance of surface nodes to their surface and of curve nodes to their
    // curve (projection distance). A projection that does not reach its
    // surface or curve within 3 voxels (or stops where the field is flat)
    // answers NaN: such a node is counted apart, not folded into the mean.
    FieldProjector proj(*domain, mesh);
    const double voxel = p.selection->materials.front().field.voxelSize();
    struct Distances {
        std::size_t nodes = 0, notProjected = 0, beyond = 0;
        double mean = 0, max = 0;
        std::vector<Index> measured;   // the nodes, in index order
        std::vector<double> distance;  // of each (NaN: not projected)
    };
    auto measure = [&](NodeKind kind, auto project) {
        std::vector<Index> nodes;
        for (std::size_t v = 0; v < mesh.nodeCount(); ++v)
            if (mesh.nodeClass[v].kind == kind && mesh.nodeClass[v].id >= 0) nodes.push_back(static_cast<Index>(v));
        std::vector<double> dist(nodes.size(), 0.0);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nodes.size(), 256), [&](const auto& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const Vec3& x = mesh.nodes[nodes[i]];
                const Vec3 y = project(mesh.nodeClass[nodes[i]].id, x);
                dist[i] = std::sqrt((x[0] - y[0]) * (x[0] - y[0]) + (x[1] - y[1]) * (x[1] - y[1]) +
                                    (x[2] - y[2]) * (x[2] - y[2]));
            }
        });
        Distances out;
        out.nodes = nodes.size();
        double sum = 0;
        std::size_t measured = 0;
        for (const double d : dist) {
            if (!std::isfinite(d)) {
                ++out.notProjected;
                continue;
            }
            out.beyond += d > 0.1 * voxel;
            sum += d;
            out.max = std::max(out.max, d);
            ++measured;
        }
        out.mean = measured ? sum / static_cast<double>(measured) : 0.0;
        out.measured = std::move(nodes);
        out.distance = std::move(dist);
        return out;
    };
    const Distances surf =
        measure(NodeKind::Surface, [&](std::int32_t id, const Vec3& x) { return proj.project(id, x); });
    j["boundary_nodes"] = surf.nodes;
    j["boundary_nodes_not_projected"] = surf.notProjected;
    // Issue 6's fidelity bound: nodes farther than 0.1 voxel from their surface
    // (the not-projected ones are farther still and counted apart above).
    j["boundary_nodes_beyond_0_1_voxel"] = surf.beyond;
    j["boundary_distance_mean"] = surf.mean;
    j["boundary_distance_max"] = surf.max;
    j["boundary_distance_mean_voxels"] = surf.mean / voxel;
    j["boundary_distance_max_voxels"] = surf.max / voxel;
    // Where the grid level's points were changed (the non-manifold repair,
    // --keep-largest, --fill-pits), the mesh follows the repaired field, whose
    // zero set there need not be near the scan's: a cell whose grid point was
    // flipped may hold no isosurface of the scan at all. The same nodes are
    // therefore also measured against the surface the mesh was extracted on,
    // and those in cells with a changed grid point are counted, so a node off
    // the scan's isosurface because of the repair is told apart from one the
    // optimiser left off (released to untangle a hex).
    if (const auto* repaired = static_cast<const octree::RepairedDomain*>(p.repairedDomain.get())) {
        FieldProjector extracted(*domain, mesh, repaired);
        const Distances own =
            measure(NodeKind::Surface, [&](std::int32_t id, const Vec3& x) { return extracted.project(id, x); });
        std::size_t inCells = 0, beyondInCells = 0;
        for (std::size_t i = 0; i < surf.measured.size(); ++i) {
            if (!repaired->nearChange(mesh.nodes[static_cast<std::size_t>(surf.measured[i])])) continue;
            ++inCells;
            beyondInCells += !(surf.distance[i] <= 0.1 * voxel);  // NaN (not projected) counts as beyond
        }
        j["boundary_nodes_in_repaired_cells"] = inCells;
        j["boundary_nodes_beyond_0_1_voxel_or_not_projected_in_repaired_cells"] = beyondInCells;
        j["extracted_surface"] = {{"boundary_nodes_beyond_0_1_voxel", own.beyond},
                                  {"boundary_nodes_not_projected", own.notProjected},
                                  {"boundary_distance_mean_voxels", own.mean / voxel},
                                  {"boundary_distance_max_voxels", own.max / voxel}};
    }
    // Curve nodes (where three materials meet, or two and the outside).
    if (!mesh.curves.empty()) {
        const Distances curve =
            measure(NodeKind::Curve, [&](std::int32_t id, const Vec3& x) { return proj.projectToCurve(id, x); });
        j["curve_nodes"] = curve.nodes;
        j["curve_nodes_not_projected"] = curve.notProjected;
        j["curve_nodes_beyond_0_1_voxel"] = curve.beyond;
        j["curve_distance_max_voxels"] = curve.max / voxel;
    }
    j["units"] = "world units of the scan (mm for medical images)";
    return j;
}

MeshOutcome runMeshPipeline(const std::string& input, const MeshSettings& settings, StageSink& sink) {
    if (settings.method == "sheets") return runSheetMethod(input, settings, sink);  // SheetMethod.cpp
    const auto t0 = Clock::now();
    Prepared p = prepare(input, settings, sink);
    std::vector<std::string> warnings;  // after prepare's (p.warnings)
    MeshOutcome out;
    out.mesh = extract(p, settings, sink);
    out.report = p.report;
    out.report["method"] = settings.method;
    out.report["extracted"] = {{"hexes", out.mesh.hexCount()}, {"nodes", out.mesh.nodeCount()}};
    out.report["pillow"] = insertSheets(out.mesh, settings, sink);
    out.report["optimization"] = optimize(out.mesh, p, settings, sink, false);
    // Hexes still inverted, or left nearly flat, sit where the grid's shape
    // asks the sheet for a convex hex no node placement gives (a one-point
    // bump at a junction of materials, a pit). Give a grid point there
    // another material (simple: no topology change;
    // octree::editNearInvertedHexes) and mesh again; keep the result when it
    // is better (Stuck::betterThan).
    if (settings.optimize) {
        const auto retriesStart = Clock::now();
        const int maxRetries = settings.method == "dual" ? settings.retries.value_or(kDefaultRetries) : 0;
        const double floor = settings.method == "dual" ? settings.retryBelow.value_or(kDefaultRetryBelow) : 0.0;
        Stuck stuck;
        if (floor > 0) stuck = stuckHexes(out.mesh, floor);
        else stuck.inverted = invertedHexes(out.mesh);
        nlohmann::json attempts = nlohmann::json::array();
        std::size_t editsKept = 0, meshedAgain = 0;
        const octree::Grid& g = p.labels.grid;
        Eigen::Matrix3d axes;
        for (int a = 0; a < 3; ++a)
            for (int c = 0; c < 3; ++c) axes(c, a) = g.axes[a][c];
        const Eigen::Matrix3d toGrid = axes.inverse();
        std::vector<std::size_t> frozen;
        std::shared_ptr<const octree::Labels> sampled;
        for (int attempt = 1; attempt <= maxRetries && !(stuck.inverted.empty() && stuck.flat.empty()); ++attempt) {
            nlohmann::json tried = {{"attempt", attempt}, {"before", stuck.counts()},
                                    {"edits", nlohmann::json::array()}, {"kept", false}};
            // inverted hexes first: while any is left, the edits go to them
            // alone; of the flat ones, the worst kMaxStuckToRetry
            std::vector<Index> work = stuck.inverted.empty() ? stuck.flat : stuck.inverted;
            if (!stuck.inverted.empty() && work.size() > kMaxStuckToRetry) {
                tried["not_meshed_because"] = "more than " + std::to_string(kMaxStuckToRetry) +
                                              " inverted hexes: not a few stuck places";
                attempts.push_back(tried);
                break;
            }
            if (work.size() > kMaxStuckToRetry) work.resize(kMaxStuckToRetry);
            std::vector<std::array<double, 3>> at;
            for (Index h : work) {
                const Vec3 c = hexCentre(out.mesh, h);
                const Eigen::Vector3d x = toGrid * Eigen::Vector3d(c[0] - g.origin[0], c[1] - g.origin[1], c[2] - g.origin[2]);
                at.push_back({x[0], x[1], x[2]});
            }
            Prepared q = p;
            const std::vector<octree::PointEdit> edits = octree::editNearInvertedHexes(q.labels, at, frozen);
            for (const auto& e : edits) {
                const auto [i, jj, k] = g.coords(e.point);
                tried["edits"].push_back({{"grid_point", {i, jj, k}}, {"at", g.point(i, jj, k)}, {"from", e.from}, {"to", e.to}});
                frozen.push_back(e.point);
            }
            if (edits.empty()) {
                tried["not_meshed_because"] =
                    "no grid point next to these hexes can change material without changing a topology";
                attempts.push_back(tried);
                break;
            }
            // the stages' progress starts over: say why
            sink.note("info", "meshing again (retry " + std::to_string(attempt) + " of " + std::to_string(maxRetries) +
                                  "): " + std::to_string(edits.size()) + " grid point(s) next to " +
                                  std::to_string(work.size()) + (stuck.inverted.empty() ? " nearly flat" : " inverted") +
                                  " hex(es) change material");
            if (!sampled) sampled = std::make_shared<const octree::Labels>(octree::sampleLabels(*p.domain, g));
            auto repaired = std::make_shared<octree::RepairedDomain>(*p.domain, *sampled, q.labels);
            const std::size_t repairedPoints = repaired->changedPoints();
            q.repairedDomain = std::move(repaired);
            HexMesh mesh = extract(q, settings, sink);
            nlohmann::json pillow = insertSheets(mesh, settings, sink);
            nlohmann::json opt = optimize(mesh, q, settings, sink, false);
            ++meshedAgain;
            Stuck now = stuckHexes(mesh, floor);
            const bool better = now.betterThan(stuck, floor);
            tried["after"] = now.counts();
            tried["kept"] = better;
            attempts.push_back(tried);
            if (better) {
                p = std::move(q);
                out.mesh = std::move(mesh);
                out.report["extracted"] = {{"hexes", out.mesh.hexCount()}, {"nodes", out.mesh.nodeCount()}};
                out.report["pillow"] = std::move(pillow);
                out.report["optimization"] = std::move(opt);
                out.report["grid"]["repaired_field_points"] = repairedPoints;
                stuck = std::move(now);
                editsKept += edits.size();
            }
        }
        if (editsKept > 0) {
            // the topology of the labels meshed (the edits are simple, so it
            // is the one before; counted again rather than assumed)
            out.report["grid"]["topology"] = topologyJson(octree::regionTopology(p.labels));
            sink.note("info", "changed the material of " + std::to_string(editsKept) +
                                  " grid point(s) where hexes stayed inverted or below scaled Jacobian " +
                                  shortNumber(floor) + " and meshed again (topology kept; retries in the report)");
        }
        if (settings.method == "dual")
            out.report["retries"] = {{"allowed", maxRetries}, {"floor", floor}, {"attempts", attempts},
                                     {"points_edited", editsKept}, {"meshed_again", meshedAgain},
                                     {"seconds", since(retriesStart)}};
        const std::string left =
            warnInverted(sink, out.mesh, stuck.inverted,
                         out.report["optimization"].value("inverted_after_untangling", std::size_t{0}),
                         meshedAgain == 0 ? "" : " (after meshing again " + std::to_string(meshedAgain) +
                                                     " time(s) with grid edits)",
                         settings.fixBoundary);
        if (!left.empty()) warnings.push_back(left);
        if (!stuck.flat.empty()) {
            // Not inverted, but nearly flat: a solver accepts them and its
            // accuracy suffers there (JHU at --size 1 ended at 0.027 after
            // three retries without a word).
            const Vec3 c = hexCentre(out.mesh, stuck.flat.front());
            std::string msg = std::to_string(stuck.flat.size()) + " hex(es) stay nearly flat (scaled Jacobian below " +
                              shortNumber(floor) + ", lowest " + shortNumber(stuck.minValid) + " at (" +
                              shortNumber(c[0]) + ", " + shortNumber(c[1]) + ", " + shortNumber(c[2]) + "))" +
                              (meshedAgain == 0 ? "" : " after meshing again " + std::to_string(meshedAgain) + " time(s)") +
                              (maxRetries == 0 ? "; --retries would try grid edits there, or another --size may avoid them"
                                               : "; another --size may avoid them");
            sink.note("warning", msg);
            warnings.push_back(msg);
        }
    }
    {
        Stage st(sink, "fidelity");
        out.report["fidelity"] = fidelity(out.mesh, p);
        st.finish();
    }
    nlohmann::json perMaterial;
    std::map<std::int32_t, std::size_t> hexes;
    for (auto m : out.mesh.material) ++hexes[m];
    for (auto [m, n] : hexes) perMaterial.push_back({{"material", m}, {"hexes", n}});
    out.report["materials"] = perMaterial;
    warnings.insert(warnings.begin(), p.warnings.begin(), p.warnings.end());
    out.report["warnings"] = warnings;
    out.report["pipeline_seconds"] = since(t0);
    return out;
}

}  // namespace isohex::pipeline

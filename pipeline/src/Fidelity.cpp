#include "isohex/pipeline/Fidelity.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/RepairedDomain.hpp"
#include "isohex/pipeline/FieldProjector.hpp"
#include "isohex/smoothing/NodePlace.hpp"

namespace isohex::pipeline {

namespace {

// Distances of the nodes of one kind, with each node's distance kept.
struct MeasuredNodes {
    NodeDistances summary;
    std::vector<Index> nodes;      // the nodes, in index order
    std::vector<double> distance;  // of each (NaN: not projected)
};

// distanceOf(v) of every node v of `nodes`, in parallel, summed in node order.
template <class Distance>
MeasuredNodes measureNodes(std::vector<Index> nodes, double voxel, const Distance& distanceOf) {
    std::vector<double> dist(nodes.size(), 0.0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nodes.size(), 256), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) dist[i] = distanceOf(nodes[i]);
    });
    MeasuredNodes out;
    NodeDistances& s = out.summary;
    s.nodes = nodes.size();
    double sum = 0;
    std::size_t measured = 0;
    for (const double d : dist) {
        if (!std::isfinite(d)) {
            ++s.notProjected;
            continue;
        }
        s.beyond += d > 0.1 * voxel;
        sum += d;
        s.max = std::max(s.max, d);
        ++measured;
    }
    s.mean = measured ? sum / static_cast<double>(measured) : 0.0;
    if (measured) {
        std::vector<double> sorted;
        sorted.reserve(measured);
        for (const double d : dist)
            if (std::isfinite(d)) sorted.push_back(d);
        const auto rank = static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(measured))) - 1;
        std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(rank), sorted.end());
        s.p95 = sorted[rank];
    }
    out.nodes = std::move(nodes);
    out.distance = std::move(dist);
    return out;
}

// Distance of every node of `kind` (with an id) to project(id, x).
template <class Project>
MeasuredNodes measure(const HexMesh& mesh, NodeKind kind, double voxel, const Project& project) {
    std::vector<Index> nodes;
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v)
        if (mesh.nodeClass[v].kind == kind && mesh.nodeClass[v].id >= 0) nodes.push_back(static_cast<Index>(v));
    return measureNodes(std::move(nodes), voxel, [&](Index v) {
        const Vec3& x = mesh.nodes[static_cast<std::size_t>(v)];
        const Vec3 y = project(mesh.nodeClass[static_cast<std::size_t>(v)].id, x);
        return std::sqrt((x[0] - y[0]) * (x[0] - y[0]) + (x[1] - y[1]) * (x[1] - y[1]) + (x[2] - y[2]) * (x[2] - y[2]));
    });
}

// Junction nodes (curve nodes with no named curve, where four or more
// materials meet): the distance to the farthest surface around each.
std::optional<NodeDistances> measureJunctions(const HexMesh& mesh, const FieldProjector& proj, double voxel) {
    const smoothing::JunctionSurfaces junctions = smoothing::junctionSurfaces(mesh);
    if (junctions.nodes.empty()) return std::nullopt;
    return measureNodes(junctions.nodes, voxel, [&](Index v) {
               return smoothing::distanceFromPlace(mesh, proj, junctions, v, mesh.nodes[static_cast<std::size_t>(v)]);
           })
        .summary;
}

// Each material's hex volume, computed in parallel and summed in hex order:
// the same totals for any thread count.
std::map<std::int32_t, double> meshVolumes(const HexMesh& mesh) {
    std::map<std::int32_t, double> meshVolume;
    std::vector<double> vol(mesh.hexCount());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, vol.size(), 4096), [&](const auto& r) {
        for (std::size_t h = r.begin(); h != r.end(); ++h) vol[h] = hexVolume(hexCoords(mesh, static_cast<Index>(h)));
    });
    for (std::size_t h = 0; h < vol.size(); ++h) meshVolume[mesh.material[h]] += vol[h];
    return meshVolume;
}

// Volumes: each material's mesh against its isosurface (OpenVDB's own
// polygonisation of its field's zero set) and, for labels, its voxels.
void measureVolumes(const HexMesh& mesh, const Prepared& p, FidelityResult& f) {
    double isoTotal = 0, meshTotal = 0, voxTotal = 0;
    const double voxelVolume = p.volume->spacing[0] * p.volume->spacing[1] * p.volume->spacing[2];
    std::map<std::int32_t, double> meshVolume = meshVolumes(mesh);
    f.labels = p.volume->kind == imaging::VolumeKind::Labels;
    for (const auto& m : p.selection->materials) {
        MaterialFidelity mf;
        mf.material = m.id;
        mf.volumeIsosurface = isosurfaceVolume(m.field.grid());
        mf.volumeMesh = meshVolume.count(m.id) ? meshVolume[m.id] : 0.0;
        isoTotal += mf.volumeIsosurface;
        meshTotal += mf.volumeMesh;
        if (f.labels) {
            // A label's 0.5-isosurface rounds its voxels' corners off, so for thin
            // labels it encloses clearly less than the segmentation's own voxels;
            // both references are reported.
            mf.volumeVoxels = static_cast<double>(m.voxels) * voxelVolume;
            voxTotal += *mf.volumeVoxels;
        }
        f.materials.push_back(mf);
    }
    // Several labels: the labels' own isosurfaces leave gaps where three
    // labels (or two and the outside) meet, so their sum falls short of the
    // labelled region, while the mesh partitions it. The total is compared
    // with the union's 0.5-isosurface (the surface the outer boundary is
    // contoured on); the sum is reported beside it.
    if (f.labels && p.selection->materials.size() > 1) {
        f.volumeLabelsIsosurfaces = isoTotal;
        isoTotal = isosurfaceVolume(*labelUnionField(*p.selection));
        f.volumeIsosurfaceOf = "union of the selected labels";
    } else {
        f.volumeIsosurfaceOf = f.labels ? "label" : "field";
    }
    f.volumeMesh = meshTotal;
    f.volumeIsosurface = isoTotal;
    f.volumeVoxels = voxTotal;
}

// Where the grid's points were changed (the non-manifold repair, keepLargest,
// fillPits), the mesh follows the repaired field, whose zero set there need
// not be near the scan's: a cell whose grid point was flipped may hold no
// isosurface of the scan at all. The same nodes are therefore also measured
// against the surface the mesh was contoured on, and those in cells with a
// changed grid point are counted, so a node off the scan's isosurface because
// of the repair is told apart from one the optimiser left off.
RepairedFidelity measureRepaired(const HexMesh& mesh, const SelectionDomain& domain,
                                 const octree::RepairedDomain& repaired, const MeasuredNodes& surf, double voxel) {
    FieldProjector extracted(domain, mesh, &repaired);
    RepairedFidelity r;
    r.extracted = measure(mesh, NodeKind::Surface, voxel,
                          [&](std::int32_t id, const Vec3& x) { return extracted.project(id, x); })
                      .summary;
    for (std::size_t i = 0; i < surf.nodes.size(); ++i) {
        if (!repaired.nearChange(mesh.nodes[static_cast<std::size_t>(surf.nodes[i])])) continue;
        ++r.nodesInRepairedCells;
        r.beyondOrNotProjectedInRepairedCells += !(surf.distance[i] <= 0.1 * voxel);  // NaN counts as beyond
    }
    return r;
}

}  // namespace

FidelityResult fidelity(const HexMesh& mesh, const Prepared& p) {
    const auto* domain = static_cast<const SelectionDomain*>(p.domain.get());
    FidelityResult f;
    measureVolumes(mesh, p, f);
    FieldProjector proj(*domain, mesh);
    f.voxel = p.selection->materials.front().field.voxelSize();
    const MeasuredNodes surf =
        measure(mesh, NodeKind::Surface, f.voxel, [&](std::int32_t id, const Vec3& x) { return proj.project(id, x); });
    f.boundary = surf.summary;
    if (const auto* repaired = static_cast<const octree::RepairedDomain*>(p.repairedDomain.get()))
        f.repaired = measureRepaired(mesh, *domain, *repaired, surf, f.voxel);
    // Curve nodes (where three materials meet, or two and the outside).
    if (!mesh.curves.empty())
        f.curves = measure(mesh, NodeKind::Curve, f.voxel,
                           [&](std::int32_t id, const Vec3& x) { return proj.projectToCurve(id, x); })
                       .summary;
    f.junctions = measureJunctions(mesh, proj, f.voxel);
    return f;
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

}  // namespace isohex::pipeline

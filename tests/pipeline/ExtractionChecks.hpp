// Shared by the extraction tests: running the pipeline up to dual contouring,
// and the topology of surfaces (the mesh's, OpenVDB volumeToMesh's) to compare.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <openvdb/openvdb.h>
#include <tbb/parallel_for.h>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/octree/DualContour.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/pipeline/Prepare.hpp"

namespace isohex::testsupport {

// The shared data folder and the phantoms' folder (environment, else defaults).
std::string sharedData();
std::string phantoms();

struct QuietSink : pipeline::StageSink {
    void begin(std::string_view) override {}
    void progress(double) override {}
    void end(std::string_view, double) override {}
    void note(std::string_view, const std::string&) override {}
};

struct Extracted {
    pipeline::Prepared p;
    HexMesh mesh;
    octree::ExtractStats stats;
};

// The pipeline up to dual contouring (no sheet, no optimiser, the valid start).
Extracted extractOnly(const std::string& input, pipeline::MeshSettings s);

pipeline::MeshSettings intensity(std::optional<double> iso, std::optional<double> size, bool keepLargest = false);
pipeline::MeshSettings isosurfaceTopology(pipeline::MeshSettings s);
pipeline::MeshSettings labels();

// validate() clean except inverted hexes (counted in *inverted); a failure is
// added with the report.
bool topologicallyValid(const HexMesh& m, std::size_t* inverted = nullptr);

// Components and Euler characteristic V - E + F of a polygon surface given
// by vertex ids (vertices shared between polygons by id).
struct SurfaceTopology {
    std::size_t components = 0;
    long long euler = 0;
    std::size_t faces = 0;
};

template <class Polygons>
SurfaceTopology polygonTopology(const Polygons& polys) {
    std::map<std::size_t, std::size_t> vid;  // compact vertex ids
    DisjointSets<std::size_t> sets;
    auto id = [&](std::size_t v) {
        auto [it, fresh] = vid.emplace(v, sets.size());
        if (fresh) sets.add();
        return it->second;
    };
    std::set<std::pair<std::size_t, std::size_t>> edges;
    SurfaceTopology t;
    for (const auto& poly : polys) {
        ++t.faces;
        const std::size_t n = poly.size();
        for (std::size_t i = 0; i < n; ++i) {
            const std::size_t a = id(poly[i]), b = id(poly[(i + 1) % n]);
            edges.emplace(std::min(a, b), std::max(a, b));
            sets.unite(a, b);
        }
    }
    t.components = sets.countSets();
    t.euler = static_cast<long long>(sets.size()) - static_cast<long long>(edges.size()) +
              static_cast<long long>(t.faces);
    return t;
}

// The boundary of material m's hexes: boundary quads of its hexes and the
// interface quads it shares with another material.
SurfaceTopology meshRegionTopology(const HexMesh& mesh, const Topology& topo, std::int32_t m);

// The field sampled at the extraction grid's points (the grid's outer layer
// outside, as sampleLabels does), as an OpenVDB grid with the grid's own
// (possibly anisotropic, oblique) transform.
template <class Field>
openvdb::FloatGrid::Ptr sampleOnGrid(const octree::Grid& g, const Field& value) {
    openvdb::math::Mat4d mat = openvdb::math::Mat4d::identity();
    for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) mat(a, c) = g.axes[a][c];
    for (int c = 0; c < 3; ++c) mat(3, c) = g.origin[c];
    auto grid = openvdb::FloatGrid::create(1.0f);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(mat));
    const auto [nx, ny, nz] = g.dims;
    std::vector<float> v(g.size(), 1.0f);
    tbb::parallel_for(1, nz - 1, [&](int k) {
        for (int j = 1; j < ny - 1; ++j)
            for (int i = 1; i < nx - 1; ++i) v[g.index(i, j, k)] = static_cast<float>(value(g.point(i, j, k)));
    });
    auto acc = grid->getAccessor();
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) acc.setValue(openvdb::Coord(i, j, k), v[g.index(i, j, k)]);
    return grid;
}

// volumeToMesh's surface of a grid (iso 0).
SurfaceTopology vdbTopology(const openvdb::FloatGrid& grid);

// volumeToMesh's surface of material m's grid points (inside; all others outside).
SurfaceTopology labelSurface(const octree::Labels& l, std::int32_t m);

}  // namespace isohex::testsupport

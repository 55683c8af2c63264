#include "ExtractionChecks.hpp"

#include <cstdlib>
#include <filesystem>
#include <stdexcept>

#include <gtest/gtest.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <nlohmann/json.hpp>

#include "isohex/core/Validate.hpp"

namespace isohex::testsupport {

std::string sharedData() {
    if (const char* env = std::getenv("ISOHEX_SHARED_DATA")) return env;
    return "../shared/data";
}

std::string phantoms() {
    if (const char* env = std::getenv("ISOHEX_PHANTOMS")) return env;
    return ISOHEX_PHANTOMS_DIR;
}

Extracted extractOnly(const std::string& input, pipeline::MeshSettings s) {
    if (!std::filesystem::exists(input)) throw std::runtime_error("missing input " + input);
    s.pillow = false;
    s.optimize = false;
    s.tangledStart = false;  // these tests check the valid start's held-back positions, whatever the default
    QuietSink sink;
    Extracted r;
    r.p = pipeline::prepare(input, s, sink);
    // what pipeline::contour does without --mesh-exterior, keeping the statistics
    r.mesh = octree::dualContourHexes(r.p.labels, r.p.extractionDomain(), {}, &r.stats);
    return r;
}

SurfaceTopology meshRegionTopology(const HexMesh& mesh, const Topology& topo, std::int32_t m) {
    std::vector<std::vector<std::size_t>> polys;
    for (const Quad& q : topo.quads) {
        const std::int32_t a = mesh.material[q.hex[0]];
        const std::int32_t b = q.boundary() ? -1 : mesh.material[q.hex[1]];
        if (a == b || (a != m && b != m)) continue;
        polys.push_back({static_cast<std::size_t>(q.nodes[0]), static_cast<std::size_t>(q.nodes[1]),
                         static_cast<std::size_t>(q.nodes[2]), static_cast<std::size_t>(q.nodes[3])});
    }
    return polygonTopology(polys);
}

SurfaceTopology vdbTopology(const openvdb::FloatGrid& grid) {
    std::vector<openvdb::Vec3s> pts;
    std::vector<openvdb::Vec3I> tris;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(grid, pts, tris, quads, 0.0);
    std::vector<std::vector<std::size_t>> polys;
    for (const auto& t : tris) polys.push_back({t[0], t[1], t[2]});
    for (const auto& q : quads) polys.push_back({q[0], q[1], q[2], q[3]});
    return polygonTopology(polys);
}

SurfaceTopology labelSurface(const octree::Labels& l, std::int32_t m) {
    auto grid = openvdb::FloatGrid::create(1.0f);
    auto acc = grid->getAccessor();
    const auto [nx, ny, nz] = l.grid.dims;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                if (l.material[l.grid.index(i, j, k)] == m) acc.setValue(openvdb::Coord(i, j, k), -1.0f);
    return vdbTopology(*grid);
}

bool topologicallyValid(const HexMesh& m, std::size_t* inverted) {
    ValidityReport v = validate(m);
    if (inverted) *inverted = v.defects.count("inverted_hex") ? v.defects.at("inverted_hex").count : 0;
    v.defects.erase("inverted_hex");
    if (!v.ok()) ADD_FAILURE() << toJson(v).dump();
    return v.ok();
}

pipeline::MeshSettings intensity(std::optional<double> iso, std::optional<double> size, bool keepLargest) {
    pipeline::MeshSettings s;
    s.select.iso = iso;
    s.size = size;
    s.keepLargest = keepLargest;
    return s;
}

pipeline::MeshSettings isosurfaceTopology(pipeline::MeshSettings s) {
    s.isosurfaceTopology = true;
    return s;
}

pipeline::MeshSettings labels() {
    pipeline::MeshSettings s;
    s.load.labels = true;
    return s;
}

}  // namespace isohex::testsupport

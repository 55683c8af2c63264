#include "SheetMethod.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "isohex/core/Error.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/imaging/Surface.hpp"
#include "isohex/insertion/RegularGrid.hpp"
#include "isohex/insertion/SurfaceFit.hpp"
#include "isohex/smoothing/Optimize.hpp"

namespace isohex::cli {

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

bool hasSurfaceExtension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    return ext == ".stl" || ext == ".obj" || ext == ".ply" || ext == ".off";
}

// Times one stage through the sink.
template <class Fn>
auto stage(StageSink& sink, const char* name, Fn fn) {
    const auto t = Clock::now();
    sink.begin(name);
    auto r = fn();
    sink.end(name, since(t));
    return r;
}
}  // namespace

std::shared_ptr<const insertion::TriangleTree> loadTriangleTree(const std::string& path) {
    if (!hasSurfaceExtension(path))
        throw Error(path + ": not a triangle surface; give a closed .stl, .obj, .ply or .off file");
    if (!std::filesystem::exists(path)) throw Error(path + ": no such file; check the path");
    imaging::TriangleSurface s = imaging::loadSurface(path);
    return std::make_shared<insertion::TriangleTree>(std::move(s.vertices), std::move(s.triangles), path);
}

MeshOutcome runSheetMethod(const std::string& input, const MeshSettings& settings, StageSink& sink) {
    const auto t0 = Clock::now();
    if (!hasSurfaceExtension(input))
        throw Error(input + ": --method sheets meshes a closed triangle surface (.stl .obj .ply .off); "
                            "use --method dual for scans and label maps");
    if (settings.size && !(*settings.size > 0))
        throw Error("--size must be a positive length in world units (got " + std::to_string(*settings.size) + ")");
    if (settings.level) throw Error("--level is for scans; with --method sheets give the element size with --size");
    if (settings.surfaceTolerance)
        throw Error("--surface-tolerance is in voxels of a scan; --method sheets keeps surface nodes on the triangles "
                    "until its volume fit, so leave it out");
    if (settings.isosurfaceTopology)
        throw Error("--isosurface-topology chooses grid points of a sampled grid; --method sheets has none (use "
                    "--method dual)");
    auto surface = stage(sink, "load", [&] { return loadTriangleTree(input); });
    const double size = settings.size ? *settings.size : surface->meanEdgeLength();
    const auto box = surface->bounds();
    MeshOutcome out;
    out.report["input"] = {{"path", input},
                           {"triangles", surface->triangles().size()},
                           {"vertices", surface->vertices().size()},
                           {"volume", surface->volume()}};
    out.report["method"] = "sheets";
    out.report["size"] = size;
    out.mesh = stage(sink, "grid", [&] { return insertion::regularGrid(box[0], box[1], size, 0.05); });
    out.report["grid"] = {{"hexes", out.mesh.hexCount()}, {"nodes", out.mesh.nodeCount()}, {"margin", 0.05}};

    insertion::SheetGeometry geometry;
    insertion::InsertOptions io;
    io.keep = insertion::Keep::Inside;
    const insertion::InsertResult r =
        stage(sink, "sheets", [&] { return insertion::insertSheets(out.mesh, geometry, surface, io); });
    out.report["pillow"] = {{"enabled", true},
                            {"method", "two sheets along the triangles (seed 5.4), outside discarded"},
                            {"intersected_hexes", r.intersectedHexes},
                            {"flood_components", r.floodComponents},
                            {"nonmanifold_edges_fixed", r.nonManifoldEdgesFixed},
                            {"nonmanifold_nodes_fixed", r.nonManifoldNodesFixed},
                            {"hexes_moved", r.hexesMoved},
                            {"sheet_hexes", r.sheetHexes},
                            {"surface_nodes", r.surfaceNodes}};
    if (settings.optimize) {
        smoothing::SmoothingOptions so;
        so.fixBoundary = settings.fixBoundary;
        const auto t = Clock::now();
        sink.begin("optimize");
        const auto sr = smoothing::optimizeMesh(out.mesh, &geometry, so, [&](std::string_view, double f) { sink.progress(f); });
        sink.end("optimize", since(t));
        out.report["optimization"] = {{"inverted_before", sr.invertedBefore},
                                      {"inverted_after", sr.invertedAfter},
                                      {"sweeps", sr.sweeps},
                                      {"untangle_sweeps", sr.untangleSweeps},
                                      {"seconds", sr.seconds}};
        // The optimiser minimises a sum; what it leaves below the target (hexes
        // whose surface quad sits on detail smaller than an element) gets a
        // max-min pass, then the surface nodes are fitted so the boundary
        // quads enclose the triangles' volume instead of cutting chords.
        if (!settings.fixBoundary) {
            if (settings.worstHexPass)
                out.report["worst_hexes"] = stage(sink, "worst_hexes", [&] { return worstHexPass(out.mesh, &geometry, settings.worstHexTarget); });
            const auto fr =
                stage(sink, "surface_fit", [&] { return insertion::fitSurfaceVolume(out.mesh, *surface, r.surfaceId); });
            out.report["surface_fit"] = {{"method", "volume-balanced offset of surface nodes along their normal"},
                                         {"nodes", fr.nodes},
                                         {"nodes_moved", fr.nodesMoved},
                                         {"nodes_held_back", fr.nodesHeldBack},
                                         {"max_offset", fr.maxOffset},
                                         {"volume_before", fr.volumeBefore},
                                         {"volume_after", fr.volumeAfter}};
        }
    }
    // Fidelity: enclosed volumes and the distance of boundary nodes to the triangles.
    const HexQuality q = computeQuality(out.mesh);
    double volume = 0;
    for (double v : q.volume) volume += v;
    const Topology topo = buildTopology(out.mesh);
    double maxDist = 0;
    for (Index v : topo.boundaryNodes) maxDist = std::max(maxDist, std::sqrt(surface->squaredDistance(out.mesh.nodes[v])));
    const double ref = surface->volume();
    out.report["fidelity"] = {{"surface_volume", ref},
                              {"mesh_volume", volume},
                              {"volume_error", ref != 0 ? (volume - ref) / ref : 0.0},
                              {"boundary_distance_max", maxDist}};
    out.report["warnings"] = nlohmann::json::array();
    out.report["pipeline_seconds"] = since(t0);
    return out;
}

}  // namespace isohex::cli

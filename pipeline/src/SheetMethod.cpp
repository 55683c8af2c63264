#include "isohex/pipeline/SheetMethod.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "isohex/pipeline/OptimizerProgress.hpp"
#include "Stage.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/insertion/RegularGrid.hpp"
#include "isohex/pipeline/MinQuality.hpp"
#include "isohex/imaging/Surface.hpp"
#include "isohex/imaging/SurfaceVolume.hpp"
#include "isohex/smoothing/Optimize.hpp"

namespace isohex::pipeline {

namespace {

// The settings that have no meaning for the sheet method are refused.
void checkSettings(const std::string& input, const MeshSettings& settings) {
    if (!imaging::isSurfaceFile(input))
        throw SettingError({input + ": ", Setting::Method,
                            " sheets meshes a closed triangle surface (.stl .obj .ply .off); use ", Setting::Method,
                            " dual for scans and label maps"});
    checkElementSize(settings);
    if (settings.level)
        throw SettingError({Setting::Level, " is for scans; with ", Setting::Method, " sheets give the element size with ",
                            Setting::Size});
    if (settings.surfaceTolerance)
        throw SettingError({Setting::SurfaceTolerance, " is in voxels of a scan; ", Setting::Method,
                            " sheets keeps surface nodes on the triangles until its volume fit, so leave it out"});
    if (settings.maxDeviation)
        throw SettingError({Setting::Method, " sheets keeps surface nodes on the triangles until its volume fit; the "
                            "maximum deviation is in voxels of a scan, so leave it out"});
    if (settings.isosurfaceTopology)
        throw SettingError({Setting::IsosurfaceTopology, " chooses grid points of a sampled grid; ", Setting::Method,
                            " sheets has none (use ", Setting::Method, " dual)"});
}

// Untangling and optimisation with surface nodes on the triangles. The
// optimiser minimises a sum; what it leaves below the target (hexes whose
// surface quad sits on detail smaller than an element) gets a max-min pass,
// then the surface nodes are fitted so the boundary quads enclose the
// triangles' volume instead of cutting chords.
void optimizeOnTriangles(SheetMeshing& out, insertion::SheetGeometry& geometry, const insertion::TriangleTree& surface,
                         std::int32_t surfaceId, const MeshSettings& settings, StageSink& sink) {
    smoothing::SmoothingOptions so;
    so.fixBoundary = settings.fixBoundary;
    out.report.optimization = timedStage(sink, "optimize", [&] {
        PhasedProgress phased = optimizerProgress(sink, WorstHexesInStage::No);
        return smoothing::optimizeMesh(out.mesh, &geometry, so, phased.callback());
    });
    if (settings.fixBoundary) return;
    if (settings.worstHexPass)
        out.report.worstHexes = timedStage(sink, "worst_hexes", [&] {
            return worstHexPass(out.mesh, &geometry, worstHexTargetFor(out.report.path, settings), 0, nullptr,
                                [&](std::string_view, double f) { sink.progress(f); });
        });
    out.report.surfaceFit =
        timedStage(sink, "surface_fit", [&] { return insertion::fitSurfaceVolume(out.mesh, surface, surfaceId); });
}

// Enclosed volumes and the distance of boundary nodes to the triangles.
SheetFidelity measureFidelity(const HexMesh& mesh, const insertion::TriangleTree& surface) {
    const HexQuality q = computeQuality(mesh);
    SheetFidelity f;
    for (double v : q.volume) f.meshVolume += v;
    const Topology topo = buildTopology(mesh);
    for (Index v : topo.boundaryNodes)
        f.boundaryDistanceMax = std::max(f.boundaryDistanceMax, std::sqrt(surface.squaredDistance(mesh.nodes[v])));
    f.surfaceVolume = surface.volume();
    return f;
}

}  // namespace

std::shared_ptr<const insertion::TriangleTree> loadTriangleTree(const std::string& path) {
    if (!imaging::isSurfaceFile(path))
        throw Error(path + ": not a triangle surface; give a closed .stl, .obj, .ply or .off file");
    if (!std::filesystem::exists(path)) throw Error(path + ": no such file; check the path");
    imaging::TriangleSurface s = imaging::loadSurface(path);
    auto tree = std::make_shared<insertion::TriangleTree>(std::move(s.vertices), std::move(s.triangles), path);
    // Crossing triangles have no inside: the sides of the sheets are decided
    // by an inside test, and hexes there came out inverted or on the wrong side.
    if (const auto at = tree->selfIntersection()) {
        std::ostringstream m;
        m.precision(6);
        m << path << ": the surface intersects itself (triangles cross near (" << (*at)[0] << ", " << (*at)[1] << ", "
          << (*at)[2] << ")), so it has no well-defined inside; repair it (e.g. MeshLab's 'Select Self Intersecting "
          << "Faces', or remeshing the union of its parts) and retry.";
        throw Error(m.str());
    }
    return tree;
}

SheetMeshing runSheetMethod(const std::string& input, const MeshSettings& settings, StageSink& sink) {
    const Stopwatch clock;
    checkSettings(input, settings);
    auto surface = timedStage(sink, "load", [&] { return loadTriangleTree(input); });
    SheetMeshing out;
    SheetMethodReport& r = out.report;
    r.size = settings.size ? *settings.size : surface->meanEdgeLength();
    const auto box = surface->bounds();
    r.path = input;
    r.triangles = surface->triangles().size();
    r.vertices = surface->vertices().size();
    r.surfaceVolume = surface->volume();
    r.margin = 0.05;
    out.mesh = timedStage(sink, "grid", [&] { return insertion::regularGrid(box[0], box[1], r.size, r.margin); });
    r.gridHexes = out.mesh.hexCount();
    r.gridNodes = out.mesh.nodeCount();
    insertion::SheetGeometry geometry;
    insertion::InsertOptions io;
    io.keep = insertion::Keep::Inside;
    r.insert = timedStage(sink, "sheets", [&] { return insertion::insertSheets(out.mesh, geometry, surface, io); });
    if (settings.optimize) optimizeOnTriangles(out, geometry, *surface, r.insert.surfaceId, settings, sink);
    r.fidelity = measureFidelity(out.mesh, *surface);
    r.seconds = clock.seconds();
    return out;
}

}  // namespace isohex::pipeline

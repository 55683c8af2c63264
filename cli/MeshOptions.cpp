#include "MeshOptions.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>

#include "isohex/core/Error.hpp"

namespace isohex::cli {

void addMeshOptions(CLI::App* cmd, MeshArgs& a) {
    pipeline::MeshSettings& s = a.settings;
    auto* sel = "Selection";
    cmd->add_option("--iso", s.select.iso, "Intensity of the surface (default: Otsu's threshold, reported)")->group(sel);
    cmd->add_option("--inside", a.insideMode, "Which side of --iso is solid: above (bone in CT) or below (pores, air)")
        ->check(CLI::IsMember({"above", "below"}))
        ->group(sel);
    cmd->add_flag("--labels", a.labels, "Read an integer image as a label map and mesh every label (0 = background)")
        ->group(sel);
    cmd->add_option("--label", a.labelList, "Mesh only these labels, e.g. 3 or 3,7 (implies --labels)")->group(sel);
    cmd->add_flag("--keep-largest", s.keepLargest,
                  "Keep only the largest connected region of each material (drops noise specks)")
        ->group(sel);
    cmd->add_flag("--fill-pits", s.fillPits,
                  "Fill background pits and wells one element wide before meshing (the boundary sheet cannot "
                  "give their floor a good hex; topology is kept)")
        ->group(sel);
    cmd->add_flag("--isosurface-topology", s.isosurfaceTopology,
                  "Keep the components and tunnels of the isosurface drawn on the element grid (OpenVDB's "
                  "volumeToMesh), sub-element specks, pockets and tunnels included, where a local search can "
                  "(slower; the hexes at such places are poorer)")
        ->group(sel);
    cmd->add_option("--min-label-voxels", s.select.minLabelVoxels, "Drop (and report) labels with fewer voxels")
        ->group(sel);
    cmd->add_option("--smooth", s.select.smoothSigma, "Gaussian pre-smoothing, standard deviation in mm")->group(sel);
    cmd->add_option("--interpolation", a.interpolation, "Field interpolation: trilinear or quadratic")
        ->check(CLI::IsMember({"trilinear", "quadratic"}))
        ->group(sel);
    auto* in = "Input";
    cmd->add_option("--series", s.load.seriesUid, "DICOM folder: the SeriesInstanceUID to read")->group(in);
    cmd->add_option("--grid", s.load.gridName, ".vdb file: the grid to read")->group(in);
    cmd->add_option("--volume-index", s.load.volumeIndex, "4-D or multi-component image: which volume/component")
        ->check(CLI::Range(0, 2147483647))
        ->group(in);
    cmd->add_flag("--nan-as-outside", s.load.nanAsOutside, "Treat NaN/Inf voxels as outside instead of refusing")
        ->group(in);
    cmd->add_option("--max-memory", s.load.maxMemoryMB, "Refuse volumes needing more than this many MB to load, and element sizes whose mesh is estimated to need more (default: 80% of the machine's memory)")
        ->check(CLI::Validator(
            [](const std::string& v) {
                char* end = nullptr;
                const double mb = std::strtod(v.c_str(), &end);
                return end != v.c_str() && *end == '\0' && std::isfinite(mb) && mb > 0
                           ? std::string()
                           : "--max-memory takes a number of megabytes above 0 (got '" + v + "')";
            },
            "", "positive"))
        ->group(in);
    cmd->add_option("--slice-spacing", a.sliceSpacing, "Folder of 2-D slices: voxel spacing X Y Z in mm")
        ->expected(3)
        ->group(in);
    auto* grid = "Mesh";
    cmd->add_option("--size", s.size, "Element edge length in world units (mm); default: the coarsest grid level "
                                      "that keeps the surface's topology")
        ->group(grid);
    cmd->add_option("--level", s.level, "Grid level: elements 2^level voxels wide (instead of --size)")->group(grid);
    cmd->add_option_function<std::string>(
           "--method", [&s](const std::string& name) { s.method = pipeline::parseMethod(name).value(); },
           "dual (dual contouring, default), voxel (one cube per voxel, a baseline) or sheets "
                    "(surfaces only: a grid cut by two sheets along the triangles, seed 5.4)")
        ->check(CLI::IsMember({"dual", "voxel", "sheets"}))
        ->group(grid);
    cmd->add_flag("!--no-pillow", s.pillow, "Do not insert the fundamental boundary sheet")->group(grid);
    cmd->add_option("--boundary-layers", s.boundaryLayers, "Layers of hexes in the boundary sheet (default 1)")
        ->check(CLI::Range(1, 16))
        ->group(grid);
    cmd->add_flag("--mesh-exterior", s.meshExterior, "Also mesh the background out to a box around the object")
        ->group(grid);
    auto* fixBoundary = cmd->add_flag("--fix-boundary", s.fixBoundary, "Optimise interior nodes only; surface nodes stay where extracted")
        ->group(grid);
    auto* noOptimize = cmd->add_flag("!--no-optimize", s.optimize, "Skip untangling and mean-ratio optimisation")->group(grid);
    auto* noWorst = cmd->add_flag("!--no-worst-hex-pass", s.worstHexPass,
                                  "After the mean-ratio optimisation, do not run the max-min pass on the hexes "
                                  "below --worst-hex-target")
                        ->group(grid);
    cmd->add_option("--worst-hex-target", s.worstHexTarget,
                    "Scaled Jacobian the max-min pass lifts hexes towards (default 0.3). Higher can raise the "
                    "minimum on smooth surfaces, for a slightly lower mean and more time; where hexes are stuck "
                    "(thin folds, pits) it can leave more below 0.2")
        ->check(CLI::Range(0.0, 1.0))
        ->excludes(noWorst)
        ->group(grid);
    cmd->add_option("--surface-tolerance", s.surfaceTolerance,
                    "How far, in voxels, the max-min pass may leave a boundary or interface node off its "
                    "isosurface to lift a hex below --worst-hex-target (default 0.09, under the report's "
                    "0.1-voxel fidelity bound; 0 keeps every node on the surface)")
        ->check(CLI::Range(0.0, 1.0))
        ->excludes(noWorst)
        ->excludes(fixBoundary)
        ->excludes(noOptimize)
        ->group(grid);
    cmd->add_option("--retries", s.retries,
                    "When hexes stay inverted or below --retry-below after optimisation, up to this many times give "
                    "a grid point next to them another material (never changing a material's components, tunnels "
                    "or cavities) and mesh again, keeping the better result (default 3; 0 never)")
        ->check(CLI::Range(0, 16))
        ->group(grid);
    cmd->add_option("--retry-below", s.retryBelow,
                    "Scaled Jacobian below which a hex left by the optimiser counts as stuck for --retries, as an "
                    "inverted one does (default 0.05; 0: inverted hexes only). Higher gives better worst hexes for "
                    "the time of meshing again")
        ->check(CLI::Range(0.0, 1.0))
        ->group(grid);
}

void addRunOptions(CLI::App* cmd, MeshArgs& a) {
    cmd->add_option("--threads", a.threads, "Worker threads (default: all cores); results do not depend on it")
        ->check(CLI::Range(1, 1024));
    cmd->add_flag("-q,--quiet", a.quiet, "No progress output (warnings and errors still print)");
    cmd->add_flag("--log-json", a.logJson, "Progress and messages as one JSON object per line on stderr");
    cmd->add_flag("--force", a.force, "Overwrite existing output files");
}

void MeshArgs::finish() {
    settings.select.insideBelow = insideMode == "below";
    settings.select.interpolation =
        interpolation == "quadratic" ? imaging::Interpolation::Quadratic : imaging::Interpolation::Trilinear;
    if (!labelList.empty()) {
        labels = true;
        std::stringstream ss(labelList);
        std::string item;
        while (std::getline(ss, item, ',')) {
            try {
                std::size_t used = 0;
                const long v = std::stol(item, &used);
                if (used != item.size()) throw std::invalid_argument(item);
                settings.select.labels.push_back(static_cast<std::int32_t>(v));
            } catch (const std::exception&) {
                throw Error("--label expects integers separated by commas, e.g. --label 3,7 (got '" + labelList + "')");
            }
        }
    }
    settings.load.labels = labels;
    if (!sliceSpacing.empty()) settings.load.sliceSpacing = {sliceSpacing[0], sliceSpacing[1], sliceSpacing[2]};
    if (labels && settings.select.iso)
        throw Error("--iso applies to intensity images; with --labels/--label the surfaces are the label boundaries");
    if (settings.surfaceTolerance) {
        const double t = *settings.surfaceTolerance;
        if (!(t >= 0 && t <= 1))
            throw Error("--surface-tolerance must be between 0 and 1 voxel (got " + std::to_string(t) + ")");
        if (settings.fixBoundary || !settings.worstHexPass || !settings.optimize)
            throw Error("--surface-tolerance has no effect with --fix-boundary, --no-worst-hex-pass or --no-optimize "
                        "(no surface node moves off its surface there); leave it out");
    }
    if (settings.retries) {
        const int n = *settings.retries;
        if (n < 0 || n > 16) throw Error("--retries must be between 0 and 16 (got " + std::to_string(n) + ")");
    }
    if (settings.retryBelow && !(*settings.retryBelow >= 0 && *settings.retryBelow <= 1))
        throw Error("--retry-below must be a scaled Jacobian between 0 and 1 (got " +
                    std::to_string(*settings.retryBelow) + ")");
    if (settings.retries.value_or(0) > 0 || settings.retryBelow.value_or(0) > 0) {
        const std::string opt = settings.retries.value_or(0) > 0 ? "--retries" : "--retry-below";
        if (settings.method != pipeline::Method::Dual)
            throw Error(opt + " edits the element grid of --method dual; --method " +
                        std::string(pipeline::methodName(settings.method)) +
                        " has no such grid (leave the option out)");
        if (!settings.optimize)
            throw Error(opt + " has no effect with --no-optimize (the retries follow the optimiser); leave it out");
        if (settings.retries && *settings.retries == 0 && settings.retryBelow.value_or(0) > 0)
            throw Error("--retry-below has no effect with --retries 0; leave one of them out");
    }
}

}  // namespace isohex::cli

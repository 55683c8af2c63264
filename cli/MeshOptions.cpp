#include "MeshOptions.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <optional>
#include <sstream>
#include <type_traits>

#include "isohex/core/Error.hpp"

namespace isohex::cli {

namespace {

// Where a row keeps its value in the arguments.
template <class T>
using Access = T& (*)(MeshArgs&);

// The check of one value, made into the flag's validator and the column's
// message alike. Every number must be finite, and every option has a range:
// NaN, infinities and values no scan or mesh could mean (a sigma of 1e308,
// a budget of 1e300 MB) are refused the same way on the command line and in
// a manifest, before any work.
struct Check {
    enum class Kind { Finite, Range };
    Kind kind = Kind::Finite;
    double lo = 0, hi = 0;
    bool aboveLo = false;  // lo itself excluded
    std::string says;      // what a bad value must be, e.g. "must be between 1 and 16"

    bool passes(double v) const {
        if (!std::isfinite(v)) return false;
        if (kind == Kind::Finite) return true;
        return (aboveLo ? v > lo : v >= lo) && v <= hi;
    }
};

std::string numberText(double v) {
    if (v == std::floor(v) && std::fabs(v) < 1e15) return std::to_string(static_cast<long long>(v));
    std::ostringstream s;
    s << v;
    return s.str();
}

std::string withUnit(const std::string& says, const std::string& unit) { return unit.empty() ? says : says + " " + unit; }

Check finite() { return {Check::Kind::Finite, 0, 0, false, "must be a finite number"}; }
// lo <= value <= hi; `unit` ends the message, e.g. "(voxels)".
Check between(double lo, double hi, const std::string& unit = "") {
    return {Check::Kind::Range, lo, hi, false,
            withUnit("must be between " + numberText(lo) + " and " + numberText(hi), unit)};
}
// 0 < value <= hi; `says` is the message.
Check above0(double hi, const std::string& says) { return {Check::Kind::Range, 0, hi, true, says}; }

// The flag's validator for `check` on values of type V: the value must be a
// number (a whole one for an integer type) that passes the check; otherwise
// it says what the column says, with the flag and the value.
template <class V>
CLI::Validator validator(const Check& check, const std::string& flag) {
    return CLI::Validator(
        [check, flag](const std::string& v) {
            char* end = nullptr;
            const double x = std::strtod(v.c_str(), &end);
            const bool number = !v.empty() && end == v.c_str() + v.size();
            const bool whole = std::is_floating_point_v<V> || x == std::floor(x);
            if (number && check.passes(x) && whole) return std::string();
            if (number && check.passes(x)) return flag + " must be a whole number (got '" + v + "')";
            return flag + " " + check.says + " (got '" + v + "')";
        },
        "", check.says);
}

template <class T>
struct Unwrapped {
    using type = T;
};
template <class T>
struct Unwrapped<std::optional<T>> {
    using type = T;
};

// A number of type V in a field: a whole number for an integer type.
template <class V>
auto parseValue(const std::string& s) {
    if constexpr (std::is_floating_point_v<V>) return toNumber(s);
    else return toInteger(s);
}

MeshOption row(const std::string& name, const char* group, const char* help, const char* columnHelp) {
    MeshOption o;
    o.name = name;
    o.group = group;
    o.help = help;
    o.columnHelp = columnHelp;
    return o;
}

// A number (T: double, int, std::int64_t, or an optional one: unset means
// the pipeline's default).
template <class T>
MeshOption number(const std::string& name, const char* group, const char* help, const char* columnHelp, Access<T> at,
                  const Check& check) {
    using V = typename Unwrapped<T>::type;
    MeshOption o = row(name, group, help, columnHelp);
    o.addFlag = [name, help, at, check](CLI::App& cmd, MeshArgs& a) {
        return cmd.add_option("--" + name, at(a), help)->check(validator<V>(check, "--" + name));
    };
    o.setColumn = [at, check](const Field& f, MeshArgs& a) {
        const auto v = parseValue<V>(f.scalar());
        if (!check.passes(static_cast<double>(v))) throw FieldError{check.says};
        at(a) = static_cast<V>(v);
    };
    return o;
}

// An on/off switch; `negated`: the flag turns the setting off (--no-pillow).
MeshOption onOff(const std::string& name, const char* group, const char* help, const char* columnHelp,
                 Access<bool> at, bool negated = false) {
    MeshOption o = row(name, group, help, columnHelp);
    o.addFlag = [name, help, at, negated](CLI::App& cmd, MeshArgs& a) {
        return cmd.add_flag((negated ? "!--" : "--") + name, at(a), help);
    };
    o.setColumn = [at, negated](const Field& f, MeshArgs& a) { at(a) = toBool(f.scalar()) != negated; };
    return o;
}

MeshOption text(const std::string& name, const char* group, const char* help, const char* columnHelp,
                Access<std::string> at) {
    MeshOption o = row(name, group, help, columnHelp);
    o.addFlag = [name, help, at](CLI::App& cmd, MeshArgs& a) { return cmd.add_option("--" + name, at(a), help); };
    o.setColumn = [at](const Field& f, MeshArgs& a) { at(a) = f.scalar(); };
    return o;
}

// One of named values: the flag and the column take a name, the settings
// get the value.
template <class T>
MeshOption choice(const std::string& name, const char* group, const char* help, const char* columnHelp,
                  std::vector<std::pair<std::string, T>> choices, Access<T> at) {
    MeshOption o = row(name, group, help, columnHelp);
    std::vector<std::string> names;
    for (const auto& c : choices) names.push_back(c.first);
    o.addFlag = [name, help, at, choices, names](CLI::App& cmd, MeshArgs& a) {
        return cmd
            .add_option_function<std::string>(
                "--" + name, [&a, at, choices](const std::string& v) { at(a) = toChoice(v, choices); }, help)
            ->check(CLI::IsMember(names));
    };
    o.setColumn = [at, choices](const Field& f, MeshArgs& a) { at(a) = toChoice(f.scalar(), choices); };
    return o;
}

// --label 3,7: kept as text until checkSettings; a column may also separate
// the labels by ';' or ' ' (or be a JSON array).
MeshOption labelList() {
    static const char* help = "Mesh only these labels, e.g. 3 or 3,7 (implies --labels)";
    MeshOption o = row("label", "Selection", help, "labels to mesh, e.g. \"3,7\" (or 3;7)");
    o.addFlag = [](CLI::App& cmd, MeshArgs& a) { return cmd.add_option("--label", a.labelList, help); };
    o.setColumn = [](const Field& f, MeshArgs& a) {
        std::string joined;
        for (const auto& item : f.items(",; ")) {
            toInteger(item);
            joined += (joined.empty() ? "" : ",") + trim(item);
        }
        if (joined.empty()) throw FieldError{"expected label numbers such as 3,7"};
        a.labelList = joined;
    };
    return o;
}

// --slice-spacing X Y Z: three positive numbers.
MeshOption sliceSpacing() {
    static const char* help = "Folder of 2-D slices: voxel spacing X Y Z in mm";
    MeshOption o = row("slice-spacing", "Input", help, "three numbers \"X Y Z\"");
    const Check check = above0(1e6, "must be positive and at most 1000000 (mm)");
    o.addFlag = [check](CLI::App& cmd, MeshArgs& a) {
        return cmd.add_option("--slice-spacing", a.sliceSpacing, help)
            ->expected(3)
            ->check(validator<double>(check, "--slice-spacing"));
    };
    o.setColumn = [check](const Field& f, MeshArgs& a) {
        const auto items = f.items(" ;,");
        if (items.size() != 3) throw FieldError{"expected three numbers X Y Z"};
        a.sliceSpacing.clear();
        for (const auto& s : items) {
            const double v = toNumber(s);
            if (!check.passes(v)) throw FieldError{"spacings " + check.says};
            a.sliceSpacing.push_back(v);
        }
    };
    return o;
}

// "K/N" as part K of N; nullopt when it is not two whole numbers with 1 <= K <= N.
std::optional<pipeline::PartSpec> parsePart(const std::string& text) {
    const auto slash = text.find('/');
    if (slash == std::string::npos) return std::nullopt;
    try {
        std::size_t a = 0, b = 0;
        const std::string k = text.substr(0, slash), n = text.substr(slash + 1);
        const int index = std::stoi(k, &a), count = std::stoi(n, &b);
        if (a != k.size() || b != n.size() || count < 1 || index < 1 || index > count) return std::nullopt;
        return pipeline::PartSpec{index, count};
    } catch (const std::exception&) {
        return std::nullopt;
    }
}

// --part K/N: one slab of the scan, for isohex merge.
MeshOption partRow() {
    static const char* help =
        "Mesh only part K of N (e.g. 2/4): the element grid is cut across its longest axis into N slabs; join the "
        "parts' .vtu files with isohex merge (docs/SPLIT-SCANS.md)";
    static const char* says = "must be K/N with 1 <= K <= N, e.g. 2/4";
    MeshOption o = row("part", "Mesh", help, "K/N, e.g. 2/4");
    o.addFlag = [](CLI::App& cmd, MeshArgs& a) {
        return cmd
            .add_option_function<std::string>(
                "--part", [&a](const std::string& v) { a.settings.part = parsePart(v); }, help)
            ->check(CLI::Validator(
                [](const std::string& v) {
                    return parsePart(v) ? std::string() : "--part " + std::string(says) + " (got '" + v + "')";
                },
                "K/N"));
    };
    o.setColumn = [](const Field& f, MeshArgs& a) {
        a.settings.part = parsePart(f.scalar());
        if (!a.settings.part) throw FieldError{says};
    };
    return o;
}

// The selection rows: which part of the scan becomes the mesh.
void addSelectionRows(std::vector<MeshOption>& t) {
    const char* g = "Selection";
    t.push_back(number<std::optional<double>>(
        "iso", g, "Intensity of the surface (default: Otsu's threshold, reported)", "surface intensity",
        [](MeshArgs& a) -> auto& { return a.settings.select.iso; }, finite()));
    t.back().setting = Setting::Iso;
    t.push_back(choice<bool>("inside", g, "Which side of --iso is solid: above (bone in CT) or below (pores, air)",
                             "above or below", {{"above", false}, {"below", true}},
                             [](MeshArgs& a) -> auto& { return a.settings.select.insideBelow; }));
    t.push_back(onOff("labels", g, "Read an integer image as a label map and mesh every label (0 = background)",
                      "true: read as a label map, every label", [](MeshArgs& a) -> auto& { return a.labels; }));
    t.back().setting = Setting::Labels;
    t.push_back(labelList());
    t.back().setting = Setting::Label;
    t.push_back(onOff("keep-largest", g,
                      "Keep only the largest connected region of each material (drops noise specks)", "true/false",
                      [](MeshArgs& a) -> auto& { return a.settings.keepLargest; }));
    t.back().setting = Setting::KeepLargest;
    t.push_back(onOff("fill-pits", g,
                      "Fill background pits and wells one element wide before meshing (the boundary sheet cannot "
                      "give their floor a good hex; topology is kept)",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.fillPits; }));
    t.push_back(onOff("isosurface-topology", g,
                      "Keep the components and tunnels of the isosurface drawn on the element grid (OpenVDB's "
                      "volumeToMesh), sub-element specks, pockets and tunnels included, where a local search can "
                      "(slower; the hexes at such places are poorer)",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.isosurfaceTopology; }));
    t.back().setting = Setting::IsosurfaceTopology;
    t.push_back(number<std::int64_t>("min-label-voxels", g, "Drop (and report) labels with fewer voxels",
                                     "whole number",
                                     [](MeshArgs& a) -> auto& { return a.settings.select.minLabelVoxels; },
                                     between(0, 1e15, "(voxels)")));
    t.push_back(number<double>("smooth", g, "Gaussian pre-smoothing, standard deviation in mm",
                               "Gaussian sigma in mm",
                               [](MeshArgs& a) -> auto& { return a.settings.select.smoothSigma; },
                               between(0, 1e4, "(mm)")));
    t.push_back(choice<imaging::Interpolation>(
        "interpolation", g, "Field interpolation: trilinear or quadratic", "trilinear or quadratic",
        {{"trilinear", imaging::Interpolation::Trilinear}, {"quadratic", imaging::Interpolation::Quadratic}},
        [](MeshArgs& a) -> auto& { return a.settings.select.interpolation; }));
}

// The input rows: how the scan is read.
void addInputRows(std::vector<MeshOption>& t) {
    const char* g = "Input";
    t.push_back(text("series", g, "DICOM folder: the SeriesInstanceUID to read", "DICOM SeriesInstanceUID",
                     [](MeshArgs& a) -> auto& { return a.settings.load.seriesUid; }));
    t.push_back(text("grid", g, ".vdb file: the grid to read", ".vdb grid name",
                     [](MeshArgs& a) -> auto& { return a.settings.load.gridName; }));
    t.push_back(number<int>("volume-index", g, "4-D or multi-component image: which volume/component",
                            "whole number", [](MeshArgs& a) -> auto& { return a.settings.load.volumeIndex; },
                            between(0, 2147483647)));
    t.push_back(onOff("nan-as-outside", g, "Treat NaN/Inf voxels as outside instead of refusing", "true/false",
                      [](MeshArgs& a) -> auto& { return a.settings.load.nanAsOutside; }));
    t.push_back(onOff("allow-data-outside", g,
                      "Read the data files an .nhdr or .mhd header names outside the header's folder (trusted "
                      "headers only)",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.load.allowDataOutside; }));
    t.back().setting = Setting::AllowDataOutside;
    t.push_back(number<double>(
        "max-memory", g,
        "Refuse volumes needing more than this many MB to load, and element sizes whose mesh is estimated to need "
        "more (default: 80% of the machine's memory)",
        "MB", [](MeshArgs& a) -> auto& { return a.settings.load.maxMemoryMB; },
        above0(1e9, "must be a number of megabytes up to 1000000000 and above 0")));
    t.back().setting = Setting::MaxMemory;
    t.push_back(sliceSpacing());
    t.back().setting = Setting::SliceSpacing;
}

// The mesh rows: the grid, the method, the boundary sheet and the optimiser.
void addMeshRows(std::vector<MeshOption>& t) {
    const char* g = "Mesh";
    t.push_back(number<std::optional<double>>(
        "size", g,
        "Element edge length in world units (mm); default: the coarsest grid level that keeps the surface's "
        "topology",
        "element edge length (mm)", [](MeshArgs& a) -> auto& { return a.settings.size; },
        above0(1e15, "must be a positive length, at most 1e15")));
    t.back().setting = Setting::Size;
    t.push_back(number<std::optional<int>>("level", g,
                                           "Grid level: elements 2^level voxels wide (instead of --size)",
                                           "grid level 0..10", [](MeshArgs& a) -> auto& { return a.settings.level; },
                                           between(0, 10)));
    t.back().setting = Setting::Level;
    t.push_back(choice<pipeline::Method>(
        "method", g,
        "dual (dual contouring, default), voxel (one cube per voxel, a baseline) or sheets (surfaces only: a grid "
        "cut by two sheets along the triangles, seed 5.4)",
        "dual, voxel or sheets",
        {{"dual", pipeline::Method::Dual}, {"voxel", pipeline::Method::Voxel}, {"sheets", pipeline::Method::Sheets}},
        [](MeshArgs& a) -> auto& { return a.settings.method; }));
    t.back().setting = Setting::Method;
    t.push_back(onOff("no-pillow", g, "Do not insert the fundamental boundary sheet", "true/false",
                      [](MeshArgs& a) -> auto& { return a.settings.pillow; }, true));
    t.push_back(number<int>("boundary-layers", g, "Layers of hexes in the boundary sheet (default 1)", "1..16",
                            [](MeshArgs& a) -> auto& { return a.settings.boundaryLayers; }, between(1, 16)));
    t.back().setting = Setting::BoundaryLayers;
    t.push_back(onOff("adaptive", g,
                      "Coarse hexes wherever the surface allows (a 27-tree with transition templates; coarse "
                      "hexes on smooth, simple parts of the surface, the element size at features and junctions)",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.adaptive; }));
    t.back().setting = Setting::Adaptive;
    t.push_back(number<double>(
        "adaptive-deviation", g,
        "With --adaptive: how far, in grid steps, a coarse boundary quad's centre or edge midpoint may lie off the "
        "surface before its cells are refined (default 0.5)",
        "0.05..5", [](MeshArgs& a) -> auto& { return a.settings.adaptiveDeviation; }, between(0.05, 5.0)));
    t.push_back(onOff("uniform", g, "One hex per grid point everywhere (the default; the opposite of --adaptive)",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.adaptive; }, true));
    t.push_back(onOff("mesh-exterior", g, "Also mesh the background out to a box around the object", "true/false",
                      [](MeshArgs& a) -> auto& { return a.settings.meshExterior; }));
    t.back().setting = Setting::MeshExterior;
    t.push_back(partRow());
    t.back().setting = Setting::Part;
    t.push_back(onOff("fix-boundary", g, "Optimise interior nodes only; surface nodes stay where extracted",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.fixBoundary; }));
    t.push_back(onOff("no-optimize", g, "Skip untangling and mean-ratio optimisation", "true/false",
                      [](MeshArgs& a) -> auto& { return a.settings.optimize; }, true));
    t.push_back(onOff("valid-start", g,
                      "Hand the optimiser an almost untangled mesh: vertices that would invert a hex held back "
                      "towards their cell centres, the sheet's copies stepped inside every corner (the default; the "
                      "opposite of --tangled-start)",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.tangledStart; }, true));
    t.push_back(onOff("tangled-start", g,
                      "Start the optimiser with surface vertices on the surface and hexes left inverted for the "
                      "untangler, as before the valid start (for comparisons; the opposite of --valid-start)",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.tangledStart; }));
}

// "L=S" as label L and size S > 0; nullopt for anything else.
std::optional<std::pair<std::int32_t, double>> parseLabelSize(const std::string& text) {
    const auto eq = text.find('=');
    if (eq == std::string::npos) return std::nullopt;
    try {
        std::size_t a = 0, b = 0;
        const std::string l = trim(text.substr(0, eq)), s = trim(text.substr(eq + 1));
        const long label = std::stol(l, &a);
        const double size = std::stod(s, &b);
        if (a != l.size() || b != s.size() || !std::isfinite(size) || size <= 0 || size > 1e15) return std::nullopt;
        return std::pair<std::int32_t, double>{static_cast<std::int32_t>(label), size};
    } catch (const std::exception&) {
        return std::nullopt;
    }
}

// --label-size L=S, repeatable; a column takes "L=S;L=S".
MeshOption labelSizeRow() {
    static const char* help =
        "Adaptive: cells holding label L no wider than S (world units), e.g. --label-size 3=2 (repeat for more labels)";
    static const char* says = "must be LABEL=SIZE with a positive size, e.g. 3=2";
    MeshOption o = row("label-size", "Adaptive sizing", help, "LABEL=SIZE items, e.g. \"3=2;5=4\"");
    o.addFlag = [](CLI::App& cmd, MeshArgs& a) {
        return cmd
            .add_option_function<std::vector<std::string>>(
                "--label-size",
                [&a](const std::vector<std::string>& items) {
                    for (const auto& v : items) a.settings.labelSizes.push_back(*parseLabelSize(v));
                },
                help)
            ->allow_extra_args(false)
            ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll)
            ->check(CLI::Validator(
                [](const std::string& v) {
                    return parseLabelSize(v) ? std::string() : "--label-size " + std::string(says) + " (got '" + v + "')";
                },
                "L=S"));
    };
    o.setColumn = [](const Field& f, MeshArgs& a) {
        a.settings.labelSizes.clear();
        for (const auto& item : f.items("; ")) {
            const auto ls = parseLabelSize(item);
            if (!ls) throw FieldError{says};
            a.settings.labelSizes.push_back(*ls);
        }
    };
    return o;
}

// The adaptive mesher's sizing rows (pipeline/Sizing.hpp).
void addSizingRows(std::vector<MeshOption>& t) {
    const char* g = "Adaptive sizing";
    t.push_back(number<std::optional<double>>(
        "max-size", g,
        "Adaptive: no cell wider than this (world units, mm); the coarsest level of the 27-tree is the widest "
        "no wider (default: as coarse as the tree's levels allow)",
        "largest element (mm)", [](MeshArgs& a) -> auto& { return a.settings.maxSize; },
        above0(1e15, "must be a positive length, at most 1e15")));
    t.push_back(number<std::optional<double>>(
        "min-size", g,
        "Adaptive: the finest element size (world units, mm); the adaptive name of --size, which it replaces",
        "finest element (mm)", [](MeshArgs& a) -> auto& { return a.minSize; },
        above0(1e15, "must be a positive length, at most 1e15")));
    t.back().excludes = {"size", "level"};
    t.push_back(labelSizeRow());
    t.push_back(text("size-image", g,
                     "Adaptive: an image of element sizes in mm on any grid (NIfTI or any scan format); a cell is "
                     "refined while wider than the image's smallest size over it; outside the image, and where it "
                     "is 0 or NaN, nothing is asked",
                     "path of a size image", [](MeshArgs& a) -> auto& { return a.settings.sizeImage; }));
    t.back().setting = Setting::SizeImage;
    t.push_back(number<int>("grading", g,
                            "Adaptive: keep at least this many cells of each level around finer ones before the "
                            "next coarser level (default 0: the 27-tree's one-level balance alone)",
                            "0..27", [](MeshArgs& a) -> auto& { return a.settings.grading; }, between(0, 27)));
    t.push_back(onOff("no-thickness-refinement", g,
                      "Adaptive: do not refine cells where a material is thinner than two cells (on by default "
                      "with --adaptive)",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.thicknessRefinement; }, true));
    t.push_back(onOff("keep-tree", g,
                      "Adaptive: write the tree's mesh even when it has more than 90% of the uniform mesh's hexes "
                      "(by default the uniform mesh is written then, and the report says adaptive.uniform_kept)",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.keepTree; }));
}

// The rows of the max-min pass and the retries, after the optimiser's.
void addWorstHexRows(std::vector<MeshOption>& t) {
    const char* g = "Mesh";
    t.push_back(onOff("no-worst-hex-pass", g,
                      "After the mean-ratio optimisation, do not run the max-min pass on the hexes below "
                      "--worst-hex-target",
                      nullptr, [](MeshArgs& a) -> auto& { return a.settings.worstHexPass; }, true));
    t.push_back(number<std::optional<double>>(
        "worst-hex-target", g,
        "Scaled Jacobian the max-min pass lifts hexes towards (default 0.3, then 0.5 where 0.3 is reached "
        "everywhere, kept only if it lifts the minimum). Higher can raise the minimum on smooth surfaces, for a "
        "slightly lower mean and more time; where hexes are stuck (thin folds, pits) it can leave more below 0.2",
        nullptr, [](MeshArgs& a) -> auto& { return a.settings.worstHexTarget; }, between(0.0, 1.0)));
    t.back().excludes = {"no-worst-hex-pass"};
    t.push_back(number<std::optional<double>>(
        "surface-tolerance", g,
        "How far, in voxels, the max-min pass may leave a boundary or interface node off its isosurface to lift a "
        "hex below --worst-hex-target (default 0.09, under the report's 0.1-voxel fidelity bound; 0 keeps every "
        "node on the surface)",
        "voxels 0..1", [](MeshArgs& a) -> auto& { return a.settings.surfaceTolerance; },
        between(0.0, 1.0, "(voxels)")));
    t.back().setting = Setting::SurfaceTolerance;
    t.back().excludes = {"no-worst-hex-pass", "fix-boundary", "no-optimize"};
    t.push_back(number<std::optional<int>>(
        "retries", g,
        "When hexes stay inverted or below --retry-below after optimisation, up to this many times give a grid "
        "point next to them another material (never changing a material's components, tunnels or cavities) and "
        "mesh again, keeping the better result (default 3; 0 never)",
        "0..16", [](MeshArgs& a) -> auto& { return a.settings.retries; }, between(0, 16)));
    t.push_back(number<std::optional<double>>(
        "retry-below", g,
        "Scaled Jacobian below which a hex left by the optimiser counts as stuck for --retries, as an inverted one "
        "does (default 0.05; 0: inverted hexes only). Higher gives better worst hexes for the time of meshing again",
        "scaled Jacobian 0..1", [](MeshArgs& a) -> auto& { return a.settings.retryBelow; }, between(0.0, 1.0)));
}

// The rows of the certified minimum quality.
void addMinQualityRows(std::vector<MeshOption>& t) {
    const char* g = "Quality";
    t.push_back(number<std::optional<double>>(
        "min-quality", g,
        "Certified minimum scaled Jacobian of the mesh written (default 0.3 for intensity scans and label maps; "
        "0 with --no-optimize or --fix-boundary: no inverted or degenerate hex; 0.5 for triangle surfaces, 0.2 "
        "with --method sheets). The max-min pass aims at it; a mesh "
        "left below it is not written (unless --allow-below), its places are named, and the command exits with "
        "status 4",
        "scaled Jacobian 0..1", [](MeshArgs& a) -> auto& { return a.settings.minQuality; }, between(0.0, 1.0)));
    t.push_back(onOff("allow-below", g,
                      "Write the mesh even when it stays below --min-quality (the exit status is still 4 and the "
                      "report says quality.min_quality_certified false)",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.allowBelow; }));
    t.push_back(number<std::optional<double>>(
        "max-deviation", g,
        "How far, in voxels, boundary and interface nodes may leave the isosurface to lift hexes still below "
        "--min-quality after the optimiser and the retries (default 0.5, for label maps 1: their interfaces are "
        "known to a voxel; reported as quality.means)",
        "voxels 0..5", [](MeshArgs& a) -> auto& { return a.settings.maxDeviation; }, between(0.0, 5.0, "(voxels)")));
    t.back().excludes = {"no-worst-hex-pass", "fix-boundary", "no-optimize"};
    t.push_back(onOff("keep-features", g,
                      "Never remove a speck, pocket, strand or tunnel finer than an element, nor give a grid point "
                      "where labels meet another label, even where hexes stay below --min-quality after every other "
                      "means (by default such features next to those hexes, then such junction points, take the "
                      "label around them and the labels are meshed again; each one is listed in the report's "
                      "quality.means with its position and volume)",
                      "true/false", [](MeshArgs& a) -> auto& { return a.settings.removeFeatures; }, true));
    t.back().excludes = {"no-optimize"};
}

// The labels of "3,7"; throws isohex::Error naming --label.
std::vector<std::int32_t> parseLabels(const std::string& list) {
    std::vector<std::int32_t> labels;
    std::stringstream ss(list);
    std::string item;
    while (std::getline(ss, item, ',')) {
        try {
            std::size_t used = 0;
            const long v = std::stol(item, &used);
            if (used != item.size()) throw std::invalid_argument(item);
            labels.push_back(static_cast<std::int32_t>(v));
        } catch (const std::exception&) {
            throw Error("--label expects integers separated by commas, e.g. --label 3,7 (got '" + list + "')");
        }
    }
    return labels;
}

// --surface-tolerance, --retries and --retry-below with the options that
// leave them nothing to do.
void checkOptimiserOptions(const pipeline::MeshSettings& s) {
    if (s.surfaceTolerance && (s.fixBoundary || !s.worstHexPass || !s.optimize))
        throw Error("--surface-tolerance has no effect with --fix-boundary, --no-worst-hex-pass or --no-optimize "
                    "(no surface node moves off its surface there); leave it out");
    if (s.retries.value_or(0) > 0 || s.retryBelow.value_or(0) > 0) {
        const std::string opt = s.retries.value_or(0) > 0 ? "--retries" : "--retry-below";
        if (s.method != pipeline::Method::Dual)
            throw Error(opt + " edits the element grid of --method dual; --method " +
                        std::string(pipeline::methodName(s.method)) +
                        " has no such grid (leave the option out)");
        if (!s.optimize)
            throw Error(opt + " has no effect with --no-optimize (the retries follow the optimiser); leave it out");
        if (s.retries && *s.retries == 0 && s.retryBelow.value_or(0) > 0)
            throw Error("--retry-below has no effect with --retries 0; leave one of them out");
    }
    if (s.maxDeviation && (s.fixBoundary || !s.worstHexPass || !s.optimize))
        throw Error("--max-deviation has no effect with --fix-boundary, --no-worst-hex-pass or --no-optimize (no "
                    "surface node moves off its surface there); leave it out");
    if (s.maxDeviation && s.method != pipeline::Method::Dual)
        throw Error("--max-deviation is in voxels of a scan's isosurface; --method " +
                    std::string(pipeline::methodName(s.method)) + " has none (leave it out)");
}

// The adaptive sizing options: each needs --adaptive; --min-size becomes --size.
void checkSizingOptions(MeshArgs& a) {
    pipeline::MeshSettings& s = a.settings;
    std::vector<std::string> given;
    if (s.maxSize) given.push_back("--max-size");
    if (a.minSize) given.push_back("--min-size");
    if (!s.labelSizes.empty()) given.push_back("--label-size");
    if (!s.sizeImage.empty()) given.push_back("--size-image");
    if (s.grading > 0) given.push_back("--grading");
    if (!s.thicknessRefinement) given.push_back("--no-thickness-refinement");
    if (s.keepTree) given.push_back("--keep-tree");
    if (!s.adaptive && !given.empty())
        throw Error(given.front() + " sizes the cells of the adaptive mesher; add --adaptive or leave out " +
                    given.front());
    if (a.minSize) {
        if (s.size || s.level)
            throw Error(std::string("--min-size is the adaptive name of --size (the finest element size); give one of "
                                    "--min-size and ") + (s.size ? "--size" : "--level"));
        s.size = a.minSize;
        a.minSize.reset();
    }
    if (s.maxSize && s.size && *s.maxSize < *s.size)
        throw Error("--max-size (" + numberText(*s.maxSize) + ") is below the finest element size (" +
                    numberText(*s.size) + ", --size or --min-size); give a --max-size at least as large");
    if (!s.labelSizes.empty() && !a.labels)
        throw Error("--label-size sizes the cells of a label map's labels; add --labels (or --label) or leave out "
                    "--label-size");
}

}  // namespace

std::string MeshOption::column() const {
    std::string c = name;
    std::replace(c.begin(), c.end(), '-', '_');
    return c;
}

const std::vector<MeshOption>& meshOptions() {
    static const std::vector<MeshOption> table = [] {
        std::vector<MeshOption> t;
        addSelectionRows(t);
        addInputRows(t);
        addMeshRows(t);
        addSizingRows(t);
        addWorstHexRows(t);
        addMinQualityRows(t);
        return t;
    }();
    return table;
}

void addMeshOptions(CLI::App* cmd, MeshArgs& a, const std::vector<std::string>& only) {
    auto wanted = [&](const MeshOption& o) { return only.empty() || std::count(only.begin(), only.end(), o.name) > 0; };
    std::map<std::string, CLI::Option*> flags;
    for (const MeshOption& o : meshOptions())
        if (wanted(o)) flags[o.name] = o.addFlag(*cmd, a)->group(o.group);
    for (const MeshOption& o : meshOptions())
        for (const auto& other : o.excludes)
            if (wanted(o) && flags.count(other)) flags.at(o.name)->excludes(flags.at(other));
}

const MeshOption* findColumn(const std::string& column) {
    for (const MeshOption& o : meshOptions())
        if (o.columnHelp && o.column() == column) return &o;
    return nullptr;
}

void checkSettings(MeshArgs& a) {
    pipeline::MeshSettings& s = a.settings;
    if (!a.labelList.empty()) {
        a.labels = true;
        s.select.labels = parseLabels(a.labelList);
    }
    s.load.labels = a.labels;
    if (!a.sliceSpacing.empty()) s.load.sliceSpacing = {a.sliceSpacing[0], a.sliceSpacing[1], a.sliceSpacing[2]};
    if (a.labels && s.select.iso)
        throw Error("--iso applies to intensity images; with --labels/--label the surfaces are the label boundaries");
    checkOptimiserOptions(s);
    checkSizingOptions(a);
    if (s.adaptive && (s.method != pipeline::Method::Dual || s.meshExterior))
        throw Error("--adaptive coarsens the hexes of --method dual inside the object; leave out --method " +
                    std::string(pipeline::methodName(s.method)) + (s.meshExterior ? " and --mesh-exterior" : "") +
                    " or --adaptive");
}

}  // namespace isohex::cli

#include "isohex/pipeline/Prepare.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "Format.hpp"
#include "Stage.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/imaging/ScanSummary.hpp"
#include "isohex/imaging/Surface.hpp"
#include "isohex/imaging/SurfaceVolume.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/GridEdits.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/LevelChoice.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/PolygonRegions.hpp"
#include "isohex/octree/Regions.hpp"
#include "isohex/octree/RepairedDomain.hpp"
#include "isohex/octree/TopologyMatch.hpp"
#include "isohex/pipeline/MemoryEstimate.hpp"
#include "isohex/pipeline/SelectionDomain.hpp"

namespace isohex::pipeline {

namespace {

// What the phases of prepare() share besides the result.
struct PrepareState {
    const std::string& input;
    const MeshSettings& settings;
    StageSink& sink;
    Prepared p;
    std::optional<double> size;                           // settings.size, or a surface's mean edge length
    std::optional<imaging::SurfaceTopology> surfaceTopo;  // a triangle surface's own topology
    std::shared_ptr<const SelectionDomain> domain;
    openvdb::CoordBBox solid;                             // index box of the selected voxels
    std::optional<octree::LevelChoice> choice;            // when chosen by topology
    octree::Labels sampled;                               // the labels as sampled, before any change
    // A part reading its window only: the whole scan's facts, read slab by slab.
    std::optional<imaging::ScanSummary> summary;
    openvdb::math::Transform::Ptr summaryTransform;
    bool gridChosen = false;
};

// Whether voxel c is inside a selected material.
bool selected(const imaging::Volume& vol, const imaging::Selection& sel, const openvdb::Coord& c) {
    if (vol.kind == imaging::VolumeKind::Labels) {
        const std::int32_t l = vol.labels->tree().getValue(c);
        return std::any_of(sel.materials.begin(), sel.materials.end(), [&](const auto& m) { return m.id == l; });
    }
    return sel.materials.front().field.grid().tree().getValue(c) < 0;
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
                        if (selected(vol, sel, c)) acc.expand(c);
                    }
            return acc;
        },
        join);
}

// The selected voxels per voxel layer along `axis` over the volume's box.
std::vector<std::int64_t> selectedPerVoxelLayer(const imaging::Volume& vol, const imaging::Selection& sel, int axis) {
    const openvdb::CoordBBox box = vol.box;
    std::vector<std::int64_t> perVoxelLayer(static_cast<std::size_t>(box.dim()[axis]), 0);
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    tbb::parallel_for(tbb::blocked_range<int>(box.min()[axis], box.max()[axis] + 1), [&](const auto& r) {
        for (int a = r.begin(); a != r.end(); ++a) {
            std::int64_t n = 0;
            openvdb::Coord c;
            c[axis] = a;
            for (c[v] = box.min()[v]; c[v] <= box.max()[v]; ++c[v])
                for (c[u] = box.min()[u]; c[u] <= box.max()[u]; ++c[u]) n += selected(vol, sel, c);
            perVoxelLayer[static_cast<std::size_t>(a - box.min()[axis])] = n;
        }
    });
    return perVoxelLayer;
}

// The selected voxels nearest each layer of a grid (whose first layer is at
// voxel index `start` and which is `step` voxels apart), from their counts
// per voxel layer (the first at voxel index `firstVoxel`): the weights a
// split balances (partWindow).
std::vector<std::int64_t> gridLayerWeights(const std::vector<std::int64_t>& perVoxelLayer, int firstVoxel,
                                           double start, double step, int layers) {
    std::vector<std::int64_t> weights(static_cast<std::size_t>(layers), 0);
    for (std::size_t i = 0; i < perVoxelLayer.size(); ++i) {
        const double at = (static_cast<double>(firstVoxel) + static_cast<double>(i) - start) / step;
        const int l = std::clamp(static_cast<int>(std::floor(at + 0.5)), 0, layers - 1);
        weights[static_cast<std::size_t>(l)] += perVoxelLayer[i];
    }
    return weights;
}

// The grid of `step` voxels per axis over the solid box, `pad` steps wider on every side.
octree::Grid gridFor(const openvdb::math::Transform& xf, const openvdb::CoordBBox& solid,
                     const std::array<double, 3>& step, int pad) {
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

// A closed triangle surface becomes a signed-distance level set (two voxels
// per element), meshed like a scan whose iso value is 0.
void loadSurfaceInput(PrepareState& s) {
    imaging::TriangleSurface surface = imaging::loadSurface(s.input);
    imaging::checkClosedManifold(surface);
    if (!s.size) s.size = imaging::meanEdgeLength(surface);
    imaging::LevelSetOptions lso;
    lso.elementSize = *s.size;
    lso.maxMemoryMB = s.settings.load.maxMemoryMB;
    s.surfaceTopo = imaging::surfaceTopology(surface);
    s.p.facts.input.surface = SurfaceFacts{surface.triangles.size(), surface.vertices.size(), surface.volume(),
                                           surface.area(), surface.flipped, s.surfaceTopo->components,
                                           s.surfaceTopo->euler};
    s.p.volume = std::make_shared<const imaging::Volume>(imaging::surfaceToVolume(std::move(surface), lso, s.input));
}

// Stage "load": the scan (or surface) into a Volume.
void loadInput(PrepareState& s) {
    Stage st(s.sink, "load");
    if (imaging::isSurfaceFile(s.input)) {
        loadSurfaceInput(s);
    } else {
        imaging::LoadOptions lo = s.settings.load;
        lo.progress = [&](std::string_view, double f) { s.sink.progress(f); };
        lo.reading = [&](const std::string& file) { s.sink.reading(file); };
        s.p.volume = std::make_shared<const imaging::Volume>(imaging::loadVolume(s.input, lo));
    }
    st.finish();
}

// Stage "select": one implicit field per material, and the domain over them.
void selectMaterials(PrepareState& s) {
    Stage st(s.sink, "select");
    imaging::SelectOptions so = s.settings.select;
    so.progress = [&](std::string_view, double f) { s.sink.progress(f); };
    s.p.selection = std::make_shared<const imaging::Selection>(imaging::select(*s.p.volume, so));
    st.finish();
    s.domain = std::make_shared<const SelectionDomain>(s.p.volume, s.p.selection);
    s.p.domain = s.domain;
}

void chooseGrid(PrepareState& s);

// Voxels a part reads beyond its window's first and last grid layers along
// the cut axis: the interpolation's stencil (quadratic: 3 voxels) and room for
// the projections of the ghost layers' nodes; the hexes the part keeps are
// kPartGhostLayers layers further in.
constexpr int kWindowMarginVoxels = 10;

// The voxels of a part's window: its grid layers along the cut axis with
// kWindowMarginVoxels on each side, the whole scan across.
openvdb::CoordBBox windowVoxels(const PrepareState& s) {
    const PartWindow& w = *s.p.part;
    const int a = w.axis;
    const double step = s.p.facts.grid.stepVoxels[static_cast<std::size_t>(a)];
    const double start = s.solid.min()[a] - 2 * step + w.first * step;  // the window's first layer, in voxels
    const double end = start + (w.grid.dims[a] - 1) * step;
    openvdb::CoordBBox box(openvdb::Coord(0, 0, 0), s.summary->dims.offsetBy(-1));
    box.min()[a] = std::max(box.min()[a], static_cast<int>(std::floor(start)) - kWindowMarginVoxels);
    box.max()[a] = std::min(box.max()[a], static_cast<int>(std::ceil(end)) + kWindowMarginVoxels);
    return box;
}

// Why a part reads the whole scan; empty when it may read its window only.
std::string wholeReadReason(const PrepareState& s) {
    if (!s.settings.part) return {};
    if (imaging::isSurfaceFile(s.input)) return "a triangle surface";
    if (!s.size && !s.settings.level)
        return "the level is chosen by topology over the whole scan (give --size or --level)";
    return {};
}

// A part of a split scan: the whole scan's facts read slab by slab
// (imaging::summarizeScan), the grid and the part's window chosen from them,
// then only the window's voxels read and selected with the whole scan's iso
// value. False (nothing done) where the scan cannot be read so.
bool loadPartWindow(PrepareState& s) {
    ReadFacts& read = s.p.facts.input.read;
    read.whole = wholeReadReason(s);
    if (!s.settings.part || !read.whole.empty()) return false;
    Stage st(s.sink, "load");
    imaging::LoadOptions lo = s.settings.load;
    lo.progress = [&](std::string_view, double f) { s.sink.progress(f); };
    lo.reading = [&](const std::string& file) { s.sink.reading(file); };
    s.summary = imaging::summarizeScan(s.input, lo, s.settings.select);
    if (!s.summary) {
        read.whole = "the format does not stream (uncompressed NIfTI-1 and MetaImage do), or the selection "
                     "needs every voxel (labels, smoothing, non-finite voxels kept)";
        return false;
    }
    const imaging::ScanSummary& sum = *s.summary;
    s.summaryTransform = imaging::makeTransform(sum.origin, sum.spacing, sum.direction);
    chooseGrid(s);
    lo.region = windowVoxels(s);
    imaging::Volume vol = imaging::loadVolume(s.input, lo);
    vol.minValue = sum.minValue;  // the whole scan's: the iso value's range and the field's background
    vol.maxValue = sum.maxValue;
    read = {true, vol.regionStreamed, vol.voxelCount(), {}, sum.passes, sum.slabReads, {}};
    for (int a = 0; a < 3; ++a) {
        read.box[static_cast<std::size_t>(a)] = vol.box.min()[a];
        read.box[static_cast<std::size_t>(a) + 3] = vol.box.max()[a];
    }
    s.p.volume = std::make_shared<const imaging::Volume>(std::move(vol));
    st.finish();
    Stage sel(s.sink, "select");
    imaging::SelectOptions so = s.settings.select;
    so.iso = sum.iso;
    so.isoFromOtsu = sum.isoFromOtsu;
    imaging::Selection selection = imaging::select(*s.p.volume, so);
    selection.isoFromOtsu = sum.isoFromOtsu;
    selection.materials.front().voxels = sum.selectedVoxels;
    s.p.selection = std::make_shared<const imaging::Selection>(std::move(selection));
    sel.finish();
    s.domain = std::make_shared<const SelectionDomain>(s.p.volume, s.p.selection);
    s.p.domain = s.domain;
    return true;
}

// The input's and the selection's facts; notes an Otsu iso value and warns of dropped labels.
void describeInput(PrepareState& s) {
    const imaging::Volume& vol = *s.p.volume;
    const imaging::Selection& sel = *s.p.selection;
    InputFacts& in = s.p.facts.input;
    in.path = s.input;
    in.format = vol.format;
    in.pixelType = vol.pixelType;
    in.kind = vol.kind;
    in.dimensions = {vol.dims().x(), vol.dims().y(), vol.dims().z()};
    if (s.summary) in.dimensions = {s.summary->dims.x(), s.summary->dims.y(), s.summary->dims.z()};
    if (!in.read.window) {
        in.read.voxels = vol.voxelCount();
        for (int a = 0; a < 3; ++a) {
            in.read.box[static_cast<std::size_t>(a)] = vol.box.min()[a];
            in.read.box[static_cast<std::size_t>(a) + 3] = vol.box.max()[a];
        }
    }
    in.spacing = vol.spacing;
    in.origin = vol.origin;
    in.direction = vol.direction;
    in.dataRange = {vol.minValue, vol.maxValue};
    in.seriesUid = vol.seriesUid;
    SelectionFacts& sf = s.p.facts.selection;
    sf.iso = sel.iso;
    sf.isoFromOtsu = sel.isoFromOtsu;
    sf.insideBelow = sel.insideBelow;
    if (sel.iso && sel.isoFromOtsu)
        s.sink.note("info", "iso value " + std::to_string(*sel.iso) + " chosen by Otsu's method (set it with --iso)");
    for (const auto& m : sel.materials) sf.materials.push_back({m.id, m.voxels});
    for (const auto& d : sel.dropped) {
        sf.dropped.push_back(d);
        s.p.warnings.push_back("label " + std::to_string(d.label) + " has only " + std::to_string(d.voxels) +
                               " voxels and was dropped (--min-label-voxels)");
    }
}

// An element size for messages: "2", or "3.94 x 3.94 x 3.65" where the
// voxels are not cubes.
std::string sizeText(const std::array<double, 3>& size) {
    if (size[0] == size[1] && size[1] == size[2]) return shortNumber(size[0]);
    return shortNumber(size[0]) + " x " + shortNumber(size[1]) + " x " + shortNumber(size[2]);
}

// Says why the element size chosen from the scan is no coarser: a run
// meshed at voxel size everywhere (millions of hexes) because some cells of
// the next level fail its tests should not leave the user guessing. (Not in
// the parts of a split run: they would all say it.)
void noteLevelChoice(PrepareState& s, const std::array<double, 3>& size) {
    const std::optional<octree::LevelRejection>& r = s.choice->rejected;
    if (!r || s.settings.part) return;
    const std::string coarser = "size " + sizeText({2 * size[0], 2 * size[1], 2 * size[2]});
    const std::string why = r->cellTests ? "at " + coarser + ", " + r->why : coarser + " " + r->why;
    s.sink.note("info", "element size " + sizeText(size) + " chosen from the scan, no coarser: " + why +
                            ". --size sets another size: each doubling makes about an eighth of the hexes and may "
                            "lose what is thinner than an element");
}

// The grid step in voxels per axis: from the element size, the level, or
// the coarsest level that keeps the topology (octree::chooseLevel); then the grid.
void chooseGrid(PrepareState& s) {
    if (s.gridChosen) return;
    // A part reading its window only chooses it before the window is read, from the summary.
    const imaging::Volume* vol = s.summary ? nullptr : s.p.volume.get();
    const openvdb::math::Transform& xf = vol ? vol->transform() : *s.summaryTransform;
    const Vec3 spacing = vol ? vol->spacing : s.summary->spacing;
    GridFacts& grid = s.p.facts.grid;
    s.solid = vol ? solidBox(*vol, *s.p.selection) : s.summary->solid;
    if (s.solid.empty()) throw Error(s.input + ": the selection contains no voxel; nothing to mesh");
    const int pad = s.settings.meshExterior ? 1 + s.settings.exteriorMargin : 2;
    const double spacingMin = std::min({spacing[0], spacing[1], spacing[2]});
    std::array<double, 3> step{1, 1, 1};
    if (s.size) {
        for (int a = 0; a < 3; ++a) step[a] = *s.size / spacing[a];
        if (*s.size < 0.5 * spacingMin)
            s.p.warnings.push_back("--size " + std::to_string(*s.size) +
                                   " is below half the voxel spacing; the mesh cannot resolve more than the scan");
        grid.chosenBy = GridChoice::Size;
    } else if (s.settings.level) {
        if (*s.settings.level < 0 || *s.settings.level > 10)
            throw SettingError({Setting::Level, " must be between 0 and 10 (got " + std::to_string(*s.settings.level) + ")"});
        step.fill(static_cast<double>(1 << *s.settings.level));
        grid.chosenBy = GridChoice::Level;
        grid.level = *s.settings.level;
    } else {
        const octree::Grid base = gridFor(xf, s.solid, step, pad);
        s.choice = octree::chooseLevel(*s.domain, base);
        step.fill(static_cast<double>(1 << s.choice->level));
        grid.chosenBy = GridChoice::Topology;
        if (s.choice->rejected) grid.rejected = {s.choice->rejected->note()};
        grid.level = s.choice->level;
        noteLevelChoice(s, {step[0] * spacing[0], step[1] * spacing[1], step[2] * spacing[2]});
    }
    grid.stepVoxels = step;
    grid.grid = gridFor(xf, s.solid, step, pad);
    if (s.settings.part) {  // the same whole grid in every part; this part samples its window of it
        const int axis = partAxis(grid.grid);
        const auto a = static_cast<std::size_t>(axis);
        const std::vector<std::int64_t> perVoxelLayer =
            vol ? selectedPerVoxelLayer(*vol, *s.p.selection, axis) : s.summary->perLayer[a];
        const int firstVoxel = vol ? vol->box.min()[axis] : 0;
        s.p.part = partWindow(grid.grid, *s.settings.part,
                              gridLayerWeights(perVoxelLayer, firstVoxel, s.solid.min()[axis] - pad * step[a], step[a],
                                               grid.grid.dims[a]));
        grid.grid = s.p.part->grid;
    }
    s.gridChosen = true;
}

// Adds the counts of another repair round.
void addRepair(octree::RepairReport& total, const octree::RepairReport& again) {
    total.pointsAdded += again.pointsAdded;
    total.pointsRemoved += again.pointsRemoved;
    total.rounds += again.rounds;
}

// Keeps the largest region of each material (keepLargest), noting what went.
void keepLargest(PrepareState& s) {
    const std::size_t removed = octree::keepLargestComponents(s.p.labels);
    s.p.facts.grid.pointsInSmallerComponentsRemoved = removed;
    if (removed)
        s.sink.note("info", "kept the largest region of each material (" + std::to_string(removed) +
                                " grid points of smaller regions removed)");
}

// One-cell pits go after the repair (which can open them) and before the
// repaired field is built, so their new boundary gets a field too.
void fillPits(PrepareState& s) {
    if (!(s.settings.fillPits && s.settings.method == Method::Dual)) return;
    GridFacts& grid = s.p.facts.grid;
    grid.pitsFilled = octree::fillOneCellPits(s.p.labels);
    if (grid.pitsFilled == 0) return;
    addRepair(grid.repair.report, octree::repairNonManifold(s.p.labels, *s.domain));
    s.sink.note("info", "filled " + std::to_string(grid.pitsFilled) +
                            " grid points of pits and wells one element wide (--fill-pits)");
}

// Samples the labels and makes every material's boundary manifold: the
// repair (against the parts volumeToMesh keeps apart), the isosurface-topology
// search, keepLargest again (a repair can cut a thin bridge) and fillPits.
void sampleAndRepair(PrepareState& s) {
    GridFacts& grid = s.p.facts.grid;
    s.p.labels = octree::sampleLabels(*s.domain, grid.grid);
    s.sampled = s.p.labels;
    if (s.settings.keepLargest) keepLargest(s);
    s.sink.progress(0.5);
    std::vector<octree::RegionTopology> isosurface;  // volumeToMesh's, for the isosurface-topology search
    const std::vector<std::int32_t> regions =
        octree::marchingCubesRegions(s.p.labels, s.settings.isosurfaceTopology ? &isosurface : nullptr);
    const Stopwatch repairClock;
    std::optional<octree::Labels> beforeRepair;
    if (s.settings.isosurfaceTopology) beforeRepair = s.p.labels;
    RepairFacts& repair = grid.repair;
    repair.report = octree::repairNonManifold(s.p.labels, *s.domain, &regions);
    if (beforeRepair) {
        IsosurfaceTopologyFacts t;
        t.match = octree::matchPolygonTopology(s.p.labels, *beforeRepair, *s.domain, octree::volumeToMeshTables());
        t.isosurface = std::move(isosurface);
        repair.isosurfaceTopology = std::move(t);
    }
    // Not with the isosurface-topology search (unless it was discarded): the
    // pieces the isosurface has apart stay, as there.
    const bool matched = repair.isosurfaceTopology && !repair.isosurfaceTopology->match.discarded;
    if (s.settings.keepLargest && !matched && octree::keepLargestComponents(s.p.labels) > 0)
        addRepair(repair.report, octree::repairNonManifold(s.p.labels, *s.domain));
    fillPits(s);
    repair.seconds = repairClock.seconds();
    auto repaired = std::make_shared<octree::RepairedDomain>(*s.domain, s.sampled, s.p.labels);
    grid.repairedFieldPoints = repaired->changedPoints();
    if (repaired->changedPoints() > 0) s.p.repairedDomain = std::move(repaired);
}

// The topology of the labels to mesh; nothing left to mesh (an element larger
// than the object, or a level that coarse) is an error rather than an empty
// mesh handed to the optimiser.
void countTopology(PrepareState& s) {
    GridFacts& grid = s.p.facts.grid;
    grid.topology = octree::regionTopology(s.p.labels);
    if (!grid.topology.empty()) return;
    const auto sp = grid.grid.spacing();
    throw SettingError({s.input + ": no grid point lies inside the selected material(s) at this element size (" +
                            shortNumber(sp[0]) + " x " + shortNumber(sp[1]) + " x " + shortNumber(sp[2]) +
                            " world units), so there is nothing to mesh; use a smaller ",
                        Setting::Size, " or a lower ", Setting::Level});
}

// Where the isosurface-topology search fell short, in world coordinates (the
// box of the grid points the repair changed there); returns the first three
// as text for the warnings.
std::string locateUnmended(const octree::Grid& g, IsosurfaceTopologyFacts& t) {
    std::string where;
    for (const auto& pl : t.match.unmended) {
        const Vec3 a = g.point(pl.lo[0], pl.lo[1], pl.lo[2]), b = g.point(pl.hi[0], pl.hi[1], pl.hi[2]);
        UnmendedPlace u;
        for (int d = 0; d < 3; ++d) {
            u.worldMin[d] = std::min(a[d], b[d]);
            u.worldMax[d] = std::max(a[d], b[d]);
        }
        u.place = pl;
        t.unmended.push_back(u);
        if (t.unmended.size() <= 3)
            where += std::string(where.empty() ? "" : ", ") + "(" + shortNumber(u.worldMin[0]) + ", " +
                     shortNumber(u.worldMin[1]) + ", " + shortNumber(u.worldMin[2]) + ")";
    }
    if (t.match.unmended.size() > 3) where += ", ...";
    return where;
}

// Warns of every material whose boundary does not have the isosurface's
// topology after the isosurface-topology search, saying why.
void checkIsosurfaceTopology(PrepareState& s) {
    GridFacts& grid = s.p.facts.grid;
    if (!grid.repair.isosurfaceTopology) return;
    IsosurfaceTopologyFacts& t = *grid.repair.isosurfaceTopology;
    const std::string where = locateUnmended(grid.grid, t);
    const octree::TopologyMatchReport& match = t.match;
    const auto& topo = grid.topology;
    for (const auto& want : t.isosurface) {
        const auto it = std::find_if(topo.begin(), topo.end(), [&](const auto& r) { return r.material == want.material; });
        const std::size_t c = it == topo.end() ? 0 : it->components;
        const long long e = it == topo.end() ? 0 : it->euler;
        if (c == want.components && e == want.euler) continue;
        std::string why;
        if (match.discarded)
            why = "its result was not manifold and was dropped (please report this with the input)";
        else if (match.groupsMatched < match.groupsChanging)
            why = "the search mended " + std::to_string(match.groupsMatched) + " of the " +
                  std::to_string(match.groupsChanging) +
                  " places (all materials) where the repair changed the isosurface's topology" +
                  (where.empty() ? std::string() : "; not mended near " + where);
        else
            why = "every place the first repair changed was mended; a later step (--fill-pits and its repair) "
                  "changed it";
        s.p.warnings.push_back("material " + std::to_string(want.material) +
                               ": --isosurface-topology: the mesh boundary has " + std::to_string(c) +
                               " component(s), Euler characteristic " + std::to_string(e) +
                               "; the isosurface on the element grid has " + std::to_string(want.components) +
                               " component(s), Euler characteristic " + std::to_string(want.euler) + ". Why: " + why +
                               " (grid.repair.isosurface_topology in the report)");
    }
}

// The topology the mesh should have. A triangle surface has its own (its
// level set's voxels are half an element, so a voxel-level reference would
// coarsen with the size and miss what a large size loses); a scan is
// compared with the grid at voxel spacing when the user forced the grid (the
// voxel grid itself has nothing to compare with). Empty: no reference.
std::vector<octree::RegionTopology> referenceTopology(const PrepareState& s, std::string& name) {
    std::vector<octree::RegionTopology> ref;
    const imaging::Volume& vol = *s.p.volume;
    if (s.surfaceTopo) {
        octree::RegionTopology t;
        t.material = 1;
        t.components = s.surfaceTopo->components;
        t.euler = s.surfaceTopo->euler;
        ref.push_back(t);
        name = "input surface";
    } else if ((s.size || s.settings.level) && vol.voxelCount() <= 60'000'000) {
        const octree::Grid& g = s.p.facts.grid.grid;
        const octree::Grid fineGrid = gridFor(vol.transform(), s.solid, {1, 1, 1}, 2);
        const bool same = fineGrid.dims == g.dims && fineGrid.origin == g.origin && fineGrid.axes == g.axes;
        ref = s.p.facts.grid.topology;
        if (!same) {
            octree::Labels fine = octree::sampleLabels(*s.domain, fineGrid);
            if (s.settings.keepLargest) octree::keepLargestComponents(fine);
            octree::repairNonManifold(fine, *s.domain);
            ref = octree::regionTopology(fine);
        }
        name = "voxel resolution";
    }
    return ref;
}

// Warns of every material the element size drops or whose surface topology it changes.
void compareReferenceTopology(PrepareState& s) {
    if (s.p.part) return;  // a slab's topology is not the scan's (the merged mesh's is)
    std::string refName;
    const std::vector<octree::RegionTopology> ref = referenceTopology(s, refName);
    const auto& topo = s.p.facts.grid.topology;
    for (const auto& r : ref) {
        const auto it = std::find_if(topo.begin(), topo.end(), [&](const auto& t) { return t.material == r.material; });
        if (it == topo.end())
            s.p.warnings.push_back("material " + std::to_string(r.material) + " vanishes at this element size");
        else if (it->components != r.components || it->euler != r.euler)
            s.p.warnings.push_back(
                "material " + std::to_string(r.material) + ": the element size changes the topology of its surface (" +
                refName + ": " + std::to_string(r.components) + " component(s), Euler characteristic " +
                std::to_string(r.euler) + "; this mesh: " + std::to_string(it->components) +
                " component(s), Euler characteristic " + std::to_string(it->euler) + ")" +
                (s.surfaceTopo ? "; tunnels, gaps or parts thinner than about an element are closed or dropped, a "
                                 "smaller --size keeps more of them"
                               : ""));
    }
}

// Stage "octree": grid, memory check, labels, repair and the topology checks.
void buildLabels(PrepareState& s) {
    Stage st(s.sink, "octree");
    chooseGrid(s);
    checkMeshMemory(s.input, *s.p.volume, *s.p.selection, s.p.facts.grid.grid, s.settings);
    sampleAndRepair(s);
    countTopology(s);
    checkIsosurfaceTopology(s);
    compareReferenceTopology(s);
    const octree::RepairReport& rep = s.p.facts.grid.repair.report;
    if (rep.nonManifoldBefore > 0)
        s.sink.note("info", "repaired " + std::to_string(rep.nonManifoldBefore) + " non-manifold places (" +
                                std::to_string(rep.pointsAdded) + " grid points added, " +
                                std::to_string(rep.pointsRemoved) + " removed)");
    st.finish();
}

// The stages both prepare() and prepareGrid() run: the settings checked,
// the input loaded and its materials selected and described.
void loadAndSelect(PrepareState& s) {
    if (s.settings.size && s.settings.level)
        throw SettingError({Setting::Size, " and ", Setting::Level, " both given; choose one (", Setting::Size,
                            " is the element edge length in world units)"});
    checkElementSize(s.settings);
    checkPartSettings(s.settings);
    if (!loadPartWindow(s)) {
        loadInput(s);
        selectMaterials(s);
    }
    describeInput(s);
}

}  // namespace

Prepared prepare(const std::string& input, const MeshSettings& settings, StageSink& sink) {
    PrepareState s{input, settings, sink, {}, settings.size, {}, {}, {}, {}, {}, {}, {}, false};
    loadAndSelect(s);
    buildLabels(s);
    for (const auto& w : s.p.warnings) sink.note("warning", w);
    return std::move(s.p);
}

Prepared prepareGrid(const std::string& input, const MeshSettings& settings, StageSink& sink) {
    PrepareState s{input, settings, sink, {}, settings.size, {}, {}, {}, {}, {}, {}, {}, false};
    loadAndSelect(s);
    Stage st(s.sink, "octree");
    chooseGrid(s);
    st.finish();
    for (const auto& w : s.p.warnings) sink.note("warning", w);
    return std::move(s.p);
}

}  // namespace isohex::pipeline

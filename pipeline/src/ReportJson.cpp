#include "isohex/pipeline/ReportJson.hpp"

#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/Regions.hpp"
#include "isohex/octree/TopologyMatch.hpp"
#include "isohex/smoothing/ImrKernel.hpp"

namespace isohex::pipeline {

namespace {

nlohmann::json toJson(const SurfaceFacts& s) {
    return {{"triangles", s.triangles},   {"vertices", s.vertices},
            {"volume", s.volume},         {"area", s.area},
            {"flipped", s.flipped},       {"components", s.components},
            {"euler_characteristic", s.euler}};
}

nlohmann::json gridGeometryJson(const octree::Grid& g) {
    const auto s = g.spacing();
    return {{"dims", g.dims}, {"spacing", s}, {"origin", g.origin}, {"points", g.size()}};
}

// Components, Euler characteristic and total genus per material.
nlohmann::json topologyJson(const std::vector<octree::RegionTopology>& topo) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& t : topo)
        out.push_back({{"material", t.material}, {"components", t.components}, {"euler", t.euler},
                       {"genus_total", static_cast<long long>(t.components) - t.euler / 2}});
    return out;
}

// What the isosurface-topology search did and aimed at, and where it fell short.
nlohmann::json toJson(const IsosurfaceTopologyFacts& t) {
    const octree::TopologyMatchReport& m = t.match;
    nlohmann::json block = {{"groups", m.groups},
                            {"groups_changing_it", m.groupsChanging},
                            {"groups_mended", m.groupsMatched},
                            {"points_changed", m.pointsChanged},
                            {"deep_search_trials", m.deepTrials},
                            {"anneal_steps", m.annealSteps},
                            {"discarded", m.discarded},
                            {"isosurface", nlohmann::json::array()},
                            {"unmended", nlohmann::json::array()}};
    for (const auto& u : t.unmended)
        block["unmended"].push_back({{"world_min", u.worldMin},
                                     {"world_max", u.worldMax},
                                     {"grid_min", u.place.lo},
                                     {"grid_max", u.place.hi},
                                     {"points", u.place.points},
                                     {"euler_change", u.place.eulerChange}});
    for (const auto& want : t.isosurface)
        block["isosurface"].push_back(
            {{"material", want.material}, {"components", want.components}, {"euler", want.euler}});
    return block;
}

nlohmann::json toJson(const RepairFacts& r) {
    nlohmann::json j = {{"nonmanifold_blocks_before", r.report.nonManifoldBefore},
                        {"points_added", r.report.pointsAdded},
                        {"points_removed", r.report.pointsRemoved},
                        {"rounds", r.report.rounds},
                        {"seconds", r.seconds}};
    if (r.isosurfaceTopology) j["isosurface_topology"] = toJson(*r.isosurfaceTopology);
    return j;
}

nlohmann::json toJson(const StuckCounts& c) {
    return {{"inverted", c.inverted}, {"flat", c.flat}, {"min_scaled_jacobian", c.min},
            {"min_not_inverted", c.minValid}};
}

// The neighbourhood optimised again; the rest kept its nodes.
nlohmann::json toJson(const RetryRegion& r) {
    return {{"cells", r.cells},
            {"nodes", r.nodes},
            {"hexes", r.hexes},
            {"mesh_hexes", r.meshHexes},
            {"nodes_carried", r.carried},
            {"inverted_before", r.invertedBefore},
            {"untangle_sweeps", r.untangleSweeps},
            {"sweeps", r.sweeps},
            {"seconds", r.seconds}};
}

nlohmann::json toJson(const RetryAttempt& a) {
    nlohmann::json j = {{"attempt", a.attempt}, {"before", toJson(a.before)}, {"edits", nlohmann::json::array()},
                        {"kept", a.kept}};
    for (const auto& e : a.edits)
        j["edits"].push_back({{"grid_point", e.gridPoint}, {"at", e.at}, {"from", e.from}, {"to", e.to}});
    if (a.notMeshedBecause) j["not_meshed_because"] = *a.notMeshedBecause;
    if (a.after) j["after"] = toJson(*a.after);
    if (a.region) j["region"] = toJson(*a.region);
    return j;
}

double changePercent(double value, double reference) {
    return reference > 0 ? 100.0 * (value - reference) / reference : 0.0;
}

// The volumes of the fidelity report.
void volumesJson(const FidelityResult& f, nlohmann::json& j) {
    for (const auto& m : f.materials) {
        nlohmann::json mj = {{"material", m.material},
                             {"volume_mesh", m.volumeMesh},
                             {"volume_isosurface", m.volumeIsosurface},
                             {"volume_change_percent", changePercent(m.volumeMesh, m.volumeIsosurface)}};
        if (m.volumeVoxels) {
            mj["volume_voxels"] = *m.volumeVoxels;
            mj["volume_change_vs_voxels_percent"] = changePercent(m.volumeMesh, *m.volumeVoxels);
        }
        j["materials"].push_back(mj);
    }
    if (f.volumeLabelsIsosurfaces) j["volume_labels_isosurfaces"] = *f.volumeLabelsIsosurfaces;
    j["volume_isosurface_of"] = f.volumeIsosurfaceOf;
    j["volume_mesh"] = f.volumeMesh;
    j["volume_isosurface"] = f.volumeIsosurface;
    j["volume_change_percent"] = changePercent(f.volumeMesh, f.volumeIsosurface);
    if (f.volumeVoxels > 0) {
        j["volume_voxels"] = f.volumeVoxels;
        j["volume_change_vs_voxels_percent"] = 100.0 * (f.volumeMesh - f.volumeVoxels) / f.volumeVoxels;
    }
}

// The node distances of the fidelity report.
void distancesJson(const FidelityResult& f, nlohmann::json& j) {
    const double voxel = f.voxel;
    j["boundary_nodes"] = f.boundary.nodes;
    j["boundary_nodes_not_projected"] = f.boundary.notProjected;
    // The fidelity bound: nodes farther than 0.1 voxel from their surface
    // (the not-projected ones are farther still and counted apart above).
    j["boundary_nodes_beyond_0_1_voxel"] = f.boundary.beyond;
    j["boundary_distance_mean"] = f.boundary.mean;
    j["boundary_distance_max"] = f.boundary.max;
    j["boundary_distance_p95"] = f.boundary.p95;
    j["boundary_distance_mean_voxels"] = f.boundary.mean / voxel;
    j["boundary_distance_max_voxels"] = f.boundary.max / voxel;
    if (f.repaired) {
        const NodeDistances& own = f.repaired->extracted;
        j["boundary_nodes_in_repaired_cells"] = f.repaired->nodesInRepairedCells;
        j["boundary_nodes_beyond_0_1_voxel_or_not_projected_in_repaired_cells"] =
            f.repaired->beyondOrNotProjectedInRepairedCells;
        j["extracted_surface"] = {{"boundary_nodes_beyond_0_1_voxel", own.beyond},
                                  {"boundary_nodes_not_projected", own.notProjected},
                                  {"boundary_distance_mean_voxels", own.mean / voxel},
                                  {"boundary_distance_max_voxels", own.max / voxel}};
    }
    if (f.curves) {
        j["curve_nodes"] = f.curves->nodes;
        j["curve_nodes_not_projected"] = f.curves->notProjected;
        j["curve_nodes_beyond_0_1_voxel"] = f.curves->beyond;
        j["curve_distance_max_voxels"] = f.curves->max / voxel;
    }
    if (f.junctions) {
        j["junction_nodes"] = f.junctions->nodes;
        j["junction_nodes_not_projected"] = f.junctions->notProjected;
        j["junction_nodes_beyond_0_1_voxel"] = f.junctions->beyond;
        j["junction_distance_mean_voxels"] = f.junctions->mean / voxel;
        j["junction_distance_max_voxels"] = f.junctions->max / voxel;
    }
}

const char* gridChoiceName(GridChoice c) {
    switch (c) {
        case GridChoice::Size: return "size";
        case GridChoice::Level: return "level";
        case GridChoice::Topology: return "topology";
    }
    return "topology";
}

}  // namespace

nlohmann::json toJson(const InputFacts& in) {
    nlohmann::json j;
    j["path"] = in.path;
    j["format"] = in.format;
    j["pixel_type"] = in.pixelType;
    j["kind"] = in.kind == imaging::VolumeKind::Labels ? "labels" : "intensity";
    j["dimensions"] = in.dimensions;
    j["spacing"] = in.spacing;
    j["origin"] = in.origin;
    j["direction"] = in.direction;
    j["data_range"] = in.dataRange;
    j["coordinates"] = "LPS (ITK physical space), world units of the scan (mm for medical images)";
    if (!in.seriesUid.empty()) j["dicom_series"] = in.seriesUid;
    if (in.surface) j["surface"] = toJson(*in.surface);
    if (!in.surface) {
        const ReadFacts& r = in.read;
        j["read"] = {{"window", r.window},
                     {"streamed", r.streamed},
                     {"voxels", r.voxels},
                     {"box", r.box},
                     {"summary_passes", r.summaryPasses},
                     {"summary_reads", r.summaryReads}};
        if (!r.whole.empty()) j["read"]["whole_because"] = r.whole;
    }
    return j;
}

nlohmann::json toJson(const SelectionFacts& sel) {
    nlohmann::json j;
    if (sel.iso) {
        j["iso"] = *sel.iso;
        j["iso_from_otsu"] = sel.isoFromOtsu;
        j["inside"] = sel.insideBelow ? "below" : "above";
    }
    for (const auto& m : sel.materials) j["materials"].push_back({{"id", m.id}, {"voxels", m.voxels}});
    for (const auto& d : sel.dropped) j["dropped_labels"].push_back({{"label", d.label}, {"voxels", d.voxels}});
    return j;
}

nlohmann::json toJson(const GridFacts& g) {
    nlohmann::json j;
    j["chosen_by"] = gridChoiceName(g.chosenBy);
    if (g.chosenBy == GridChoice::Topology) j["rejected"] = g.rejected;
    if (g.pointsInSmallerComponentsRemoved) j["points_in_smaller_components_removed"] = *g.pointsInSmallerComponentsRemoved;
    j["pits_filled"] = g.pitsFilled;
    j["repaired_field_points"] = g.repairedFieldPoints;
    j["step_voxels"] = g.stepVoxels;
    j["element_size"] = g.grid.spacing();
    if (g.level) j["level"] = *g.level;
    j["grid"] = gridGeometryJson(g.grid);
    j["repair"] = toJson(g.repair);
    if (!g.topology.empty()) j["topology"] = topologyJson(g.topology);
    return j;
}

nlohmann::json toJson(const PillowResult& p) {
    nlohmann::json j;
    j["enabled"] = p.enabled;
    // Where contouring held vertices back to leave no hex inverted, and how
    // many of them went back to their place after the sheet (any setting).
    if (const auto& h = p.returned)
        j["held_back"] = {{"vertices", h->heldBack},
                          {"at_target", h->moved.reached},
                          {"part_way", h->moved.partway},
                          {"not_moved", h->moved.stayed},
                          {"copies_followed", h->copiesFollowed.reached + h->copiesFollowed.partway},
                          {"seconds", h->seconds}};
    if (!p.enabled) return j;
    j["layers"] = p.layers;
    j["sheets"] = p.sheets;
    j["hexes_added"] = p.hexesAdded;
    j["inverted_at_insertion"] = p.invertedAtInsertion;
    return j;
}

nlohmann::json toJson(const WorstHexPassResult& p) {
    const smoothing::WorstHexResult& w = p.result;
    nlohmann::json j = {{"target", p.options.target},
                        {"min_edge", p.options.minEdge},
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
                        {"surface_slack", p.options.surfaceSlack},
                        {"surface_nodes_within_slack", w.surfaceNodesWithinSlack},
                        {"return_seconds", w.returnSeconds},
                        {"rounds", w.rounds},
                        {"seconds", p.seconds}};
    if (p.surfaceToleranceVoxels) j["surface_tolerance_voxels"] = *p.surfaceToleranceVoxels;
    return j;
}

nlohmann::json toJson(const smoothing::BoundaryQuadResult& r) {
    return {{"sweeps", r.sweeps}, {"moves", r.moves}, {"onto_surface", r.ontoSurface}, {"seconds", r.seconds}};
}

nlohmann::json toJson(const RelaxationResult& r) {
    return {{"mean", "boundary_relaxation"},
            {"target", r.target},
            {"max_deviation_voxels", r.maxDeviationVoxels},
            {"surface_nodes_off", r.nodesOff},
            {"curve_nodes_off", r.curveNodesOff},
            {"largest_deviation_voxels", r.largestDeviationVoxels},
            {"nodes_moved", r.nodesMoved},
            {"min_scaled_jacobian_before", r.minBefore},
            {"min_scaled_jacobian_after", r.minAfter},
            {"below_target_before", r.belowBefore},
            {"below_target_after", r.belowAfter},
            {"passes", r.passes},
            {"first_step", r.firstStep},
            {"region_hexes", r.regionHexes},
            {"seconds", r.seconds}};
}

nlohmann::json toJson(const FeatureRemovalResult& r) {
    nlohmann::json features = nlohmann::json::array();
    for (const RemovedFeature& f : r.features)
        features.push_back({{"shape", shapeText(f.shape)}, {"at", f.at}, {"volume", f.volume},
                            {"grid_points", f.gridPoints}, {"material", f.material}, {"replaced_by", f.replacedBy}});
    nlohmann::json j = {{"mean", "feature_removal"},
                        {"features", features},
                        {"kept", r.kept},
                        {"min_scaled_jacobian_before", r.minBefore},
                        {"min_scaled_jacobian_after", r.minAfter},
                        {"below_target_before", r.belowBefore},
                        {"below_target_after", r.belowAfter},
                        {"repaired_points", r.repairedPoints},
                        {"seconds", r.seconds}};
    if (r.notMeshedBecause) j["not_meshed_because"] = *r.notMeshedBecause;
    if (r.region) j["region"] = toJson(*r.region);
    return j;
}

nlohmann::json toJson(const QualityCertificate& c) {
    nlohmann::json places = nlohmann::json::array();
    for (const BelowPlace& p : c.places) {
        places.push_back({{"at", p.at}, {"material", p.material}, {"scaled_jacobian", p.scaledJacobian},
                          {"cause", causeText(p.cause)}});
        if (p.shape) places.back()["shape"] = shapeText(*p.shape);
    }
    nlohmann::json means = nlohmann::json::array();
    if (c.worstHexTarget) means.push_back({{"mean", "worst_hex_pass"}, {"target", *c.worstHexTarget}});
    if (c.relaxation) means.push_back(toJson(*c.relaxation));
    nlohmann::json j = {{"min_quality_certified", c.certified},
            {"target", c.target},
            {"default_target", c.defaultTarget},
            {"achieved", c.achieved},
            {"min", c.achieved},
            {"mean", c.mean},
            {"histogram", {{"edges", kScaledJacobianBins}, {"counts", c.histogram}}},
            {"hexes_below_target", c.hexesBelow},
            {"places", places},
            {"means", means}};
    if (c.belowByShape) {
        nlohmann::json byShape = nlohmann::json::object();
        for (std::size_t i = 0; i < kLocalShapes; ++i)
            byShape[shapeText(static_cast<LocalShape>(i))] = (*c.belowByShape)[i];
        j["below_target_by_shape"] = byShape;
    }
    return j;
}

nlohmann::json toJson(const OptimizeResult& o) {
    nlohmann::json j;
    j["enabled"] = o.enabled;
    if (!o.enabled) return j;
    const smoothing::SmoothingResult& r = o.smoothingResult;
    if (o.worstHexes) j["worst_hexes"] = toJson(*o.worstHexes);
    if (o.stretch)
        j["stretch"] = {{"target", o.stretch->target},
                        {"kept", o.stretch->kept},
                        {"min_scaled_jacobian_before", o.stretch->minBefore},
                        {"min_scaled_jacobian_after", o.stretch->minAfter},
                        {"mean_scaled_jacobian_before", o.stretch->meanBefore},
                        {"mean_scaled_jacobian_after", o.stretch->meanAfter},
                        {"pass", toJson(o.stretch->pass)}};
    j["fix_boundary"] = o.fixBoundary;
    j["sweeps"] = r.sweeps;
    j["untangle_sweeps"] = r.untangleSweeps;
    j["nodes_moved"] = r.nodesMoved;
    j["node_updates"] = r.nodeUpdates;
    j["node_visits"] = r.nodeVisits;
    j["surface_node_visits"] = r.surfaceNodeVisits;
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
    j["inverted_after_untangling"] = r.untangleFailures.size();
    return j;
}

nlohmann::json toJson(const RetryResult& r) {
    nlohmann::json attempts = nlohmann::json::array();
    for (const auto& a : r.attempts) attempts.push_back(toJson(a));
    return {{"allowed", r.allowed}, {"floor", r.floor}, {"attempts", attempts},
            {"points_edited", r.pointsEdited}, {"meshed_again", r.meshedAgain}, {"seconds", r.seconds}};
}

nlohmann::json toJson(const FidelityResult& f) {
    nlohmann::json j;
    volumesJson(f, j);
    distancesJson(f, j);
    j["units"] = "world units of the scan (mm for medical images)";
    return j;
}

namespace {

// {"whole": [per level], "vertex": [...], ...}: counts per LeafForm and level.
nlohmann::json formsJson(const octree::FormCounts& counts) {
    static constexpr const char* kName[octree::kLeafForms] = {"whole", "vertex", "edge", "face", "two_face", "full"};
    nlohmann::json j = nlohmann::json::object();
    for (int f = 0; f < octree::kLeafForms; ++f) {
        std::vector<std::size_t> perLevel;
        for (const auto& level : counts) perLevel.push_back(level[static_cast<std::size_t>(f)]);
        j[kName[f]] = perLevel;
    }
    return j;
}

}  // namespace

nlohmann::json toJson(const AdaptiveFacts& a) {
    nlohmann::json checks = nlohmann::json::array();
    for (const auto& c : a.cellsByCheck)
        checks.push_back({{"junction", c[0]}, {"non_manifold", c[1]}, {"inverted", c[2]}, {"deviation", c[3]}});
    nlohmann::json j = {{"levels", a.topLevel},
                        {"hexes_per_level", a.hexesPerLevel},
                        {"uniform_hexes", a.uniformHexes},
                        {"smallest_edge", a.smallestEdge},
                        {"largest_edge", a.largestEdge},
                        {"grading", a.grading},
                        {"cells_refined",
                         {{"label_change_level_1", a.cellsAtLabelChanges},
                          {"balance_per_level", a.cellsForBalance},
                          {"surface_per_level", a.cellsBySurface},
                          {"checks_per_round", checks},
                          {"unresolved", a.unresolved},
                          {"max_size", a.sizing.maxSize},
                          {"label_size", a.sizing.labelSize},
                          {"size_image", a.sizing.sizeImage},
                          {"thickness", a.sizing.thickness},
                          {"grading_per_level", a.cellsForGrading},
                          {"requested_per_level", a.cellsRequested}}}};
    j["hexes_per_form"] = formsJson(a.hexesPerForm);
    j["leaves_per_form"] = formsJson(a.leavesPerForm);
    j["tree_hexes"] = a.treeHexes;
    j["uniform_kept"] = a.uniformKept;
    if (a.sizing.maxSizeLevel) j["max_size_level"] = *a.sizing.maxSizeLevel;
    return j;
}

nlohmann::json toJson(const MeshReport& r) {
    nlohmann::json j;
    j["input"] = toJson(r.prepared.input);
    j["selection"] = toJson(r.prepared.selection);
    j["grid"] = toJson(r.prepared.grid);
    j["method"] = methodName(r.method);
    j["extracted"] = {{"hexes", r.contouredHexes}, {"nodes", r.contouredNodes}};
    j["pillow"] = toJson(r.pillow);
    j["optimization"] = toJson(r.optimization);
    if (r.retries) j["retries"] = toJson(*r.retries);
    j["fidelity"] = toJson(r.fidelity);
    nlohmann::json perMaterial;
    for (const auto& [m, n] : r.hexesPerMaterial) perMaterial.push_back({{"material", m}, {"hexes", n}});
    j["materials"] = perMaterial;
    if (r.adaptive) j["adaptive"] = toJson(*r.adaptive);
    j["warnings"] = r.warnings;
    j["pipeline_seconds"] = r.seconds;
    if (r.part) j["part"] = toJson(*r.part);
    return j;
}

nlohmann::json toJson(const PartFacts& p) {
    const PartWindow& w = p.window;
    return {{"index", w.spec.index},
            {"count", w.spec.count},
            {"axis", w.axis},
            {"own_layers", {w.coreLo, w.coreHi}},
            {"window_layers", {w.first, w.first + w.grid.dims[static_cast<std::size_t>(w.axis)]}},
            {"ghost_layers", kPartGhostLayers},
            {"whole_grid", gridGeometryJson(w.whole)},
            {"cut_nodes", p.cutNodes}};
}

namespace {
nlohmann::json toJson(const std::optional<CutBandResult>& b) {
    if (!b) return nullptr;
    return {{"rings", kCutBandRings},
            {"nodes", b->nodes},
            {"hexes", b->hexes},
            {"scaled_jacobian_min_before", b->minBefore},
            {"scaled_jacobian_min_after", b->minAfter},
            {"inverted_before", b->invertedBefore},
            {"inverted_after", b->invertedAfter},
            {"kept", b->kept},
            {"seconds", b->seconds}};
}
}  // namespace

nlohmann::json toJson(const MergeResult& m) {
    nlohmann::json cuts = nlohmann::json::array();
    for (const auto& c : m.cuts)
        cuts.push_back({{"parts", {c.below, c.below + 1}}, {"matched_nodes", c.nodes}, {"max_offset", c.maxOffset}});
    return {{"parts", m.parts},
            {"hexes_per_part", m.hexesPerPart},
            {"nodes_per_part", m.nodesPerPart},
            {"cuts", cuts},
            {"band_pass", toJson(m.bands)},
            {"band_pass_on_scan", toJson(m.scanBands)},
            {"seconds", m.seconds}};
}

nlohmann::json toJson(const SheetMethodReport& r) {
    nlohmann::json j;
    j["input"] = {{"path", r.path}, {"triangles", r.triangles}, {"vertices", r.vertices}, {"volume", r.surfaceVolume}};
    j["method"] = "sheets";
    j["size"] = r.size;
    j["grid"] = {{"hexes", r.gridHexes}, {"nodes", r.gridNodes}, {"margin", r.margin}};
    const insertion::InsertResult& in = r.insert;
    j["pillow"] = {{"enabled", true},
                   {"method", "two sheets along the triangles (seed 5.4), outside discarded"},
                   {"intersected_hexes", in.intersectedHexes},
                   {"flood_components", in.floodComponents},
                   {"nonmanifold_edges_fixed", in.nonManifoldEdgesFixed},
                   {"nonmanifold_nodes_fixed", in.nonManifoldNodesFixed},
                   {"hexes_moved", in.hexesMoved},
                   {"sheet_hexes", in.sheetHexes},
                   {"surface_nodes", in.surfaceNodes}};
    if (const auto& o = r.optimization)
        j["optimization"] = {{"inverted_before", o->invertedBefore}, {"inverted_after", o->invertedAfter},
                             {"sweeps", o->sweeps}, {"untangle_sweeps", o->untangleSweeps}, {"seconds", o->seconds}};
    if (r.worstHexes) j["worst_hexes"] = toJson(*r.worstHexes);
    if (const auto& f = r.surfaceFit)
        j["surface_fit"] = {{"method", "volume-balanced offset of surface nodes along their normal"},
                            {"nodes", f->nodes},
                            {"nodes_moved", f->nodesMoved},
                            {"nodes_held_back", f->nodesHeldBack},
                            {"max_offset", f->maxOffset},
                            {"volume_before", f->volumeBefore},
                            {"volume_after", f->volumeAfter}};
    const SheetFidelity& f = r.fidelity;
    j["fidelity"] = {{"surface_volume", f.surfaceVolume},
                     {"mesh_volume", f.meshVolume},
                     {"volume_error", f.surfaceVolume != 0 ? (f.meshVolume - f.surfaceVolume) / f.surfaceVolume : 0.0},
                     {"boundary_distance_max", f.boundaryDistanceMax}};
    j["warnings"] = nlohmann::json::array();
    j["pipeline_seconds"] = r.seconds;
    return j;
}

}  // namespace isohex::pipeline

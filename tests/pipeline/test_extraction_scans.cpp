// The extraction on real scans and label maps, checked against things isohex
// does not compute itself: the JHU labels' volumes against the union's
// isosurface and the voxels; ch2bet at 2 mm and 1 mm (validate(), topology
// against volumeToMesh of the scan, the same extraction for 1 and 2 threads);
// curve nodes of label maps and interfaces through grid points.
// Figures are printed with the prefix "[figures]".
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>
#include <openvdb/openvdb.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/core/VecMath.hpp"
#include "isohex/octree/DualContour.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/GridEdits.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/NonManifoldRepair.hpp"
#include "isohex/octree/PolygonRegions.hpp"
#include "isohex/octree/Regions.hpp"
#include "isohex/octree/TopologyMatch.hpp"
#include "isohex/pipeline/Contour.hpp"
#include "isohex/pipeline/Fidelity.hpp"
#include "isohex/pipeline/Optimize.hpp"
#include "isohex/pipeline/Pillow.hpp"
#include "isohex/pipeline/Prepare.hpp"

#include "CornerDistances.hpp"
#include "ExtractionChecks.hpp"

using namespace isohex;
using namespace isohex::testsupport;
// Label maps: each label's surface is the 0.5 level of its trilinear
// indicator. Those surfaces do not tile the labelled region: where three
// labels meet, or two labels and the background, every label's isosurface
// cuts the corner, and the gap between them belongs to no label. The mesh is
// a partition (every point of the labelled region in exactly one hex), so its
// total volume is compared with the 0.5-isosurface of the union of the
// selected labels, and each label's volume with its voxels' volume.
TEST(Labels, JhuVolumeAgainstTheUnionIsosurfaceAndTheVoxels) {
    const Extracted r = extractOnly(sharedData() + "/JHU-WhiteMatter-labels-2mm.nii.gz", labels());
    const auto& vol = *r.p.volume;
    std::map<std::int32_t, double> meshVolume;
    for (std::size_t h = 0; h < r.mesh.hexCount(); ++h)
        meshVolume[r.mesh.material[h]] += hexVolume(hexCoords(r.mesh, static_cast<Index>(h)));
    std::set<std::int32_t> selected;
    for (const auto& m : r.p.selection->materials) selected.insert(m.id);
    // the union's indicator: 0.5 - [label selected] per voxel
    auto unionField = openvdb::FloatGrid::create(0.5f);
    unionField->setTransform(vol.labels->transform().copy());
    {
        auto in = vol.labels->getConstAccessor();
        auto out = unionField->getAccessor();
        openvdb::CoordBBox box = vol.box;
        box.expand(1);
        for (auto it = box.begin(); it; ++it) out.setValue(*it, selected.count(in.getValue(*it)) ? -0.5f : 0.5f);
    }
    const double unionIso = pipeline::isosurfaceVolume(*unionField);
    const double voxel = vol.spacing[0] * vol.spacing[1] * vol.spacing[2];
    double meshTotal = 0, labelIsoTotal = 0, voxelTotal = 0, worstVoxelChange = 0;
    for (const auto& m : r.p.selection->materials) {
        const double iso = pipeline::isosurfaceVolume(m.field.grid());
        const double vox = static_cast<double>(m.voxels) * voxel;
        meshTotal += meshVolume[m.id];
        labelIsoTotal += iso;
        voxelTotal += vox;
        worstVoxelChange = std::max(worstVoxelChange, std::abs(meshVolume[m.id] - vox) / vox);
        std::cout << "[figures] jhu label " << m.id << ": mesh " << meshVolume[m.id] << ", 0.5-isosurface " << iso
                  << " (" << 100 * (meshVolume[m.id] - iso) / iso << "%), voxels " << vox << " ("
                  << 100 * (meshVolume[m.id] - vox) / vox << "%)\n";
    }
    std::cout << "[figures] jhu total: mesh " << meshTotal << "; union 0.5-isosurface " << unionIso << " ("
              << 100 * (meshTotal - unionIso) / unionIso << "%); sum of the labels' 0.5-isosurfaces " << labelIsoTotal
              << " (" << 100 * (meshTotal - labelIsoTotal) / labelIsoTotal << "%); voxels " << voxelTotal << " ("
              << 100 * (meshTotal - voxelTotal) / voxelTotal << "%); worst label vs its voxels "
              << 100 * worstVoxelChange << "%\n";
    EXPECT_LT(std::abs(meshTotal - unionIso) / unionIso, 0.02);
}

// Issue 4: the brain with --keep-largest at 2 mm and 1 mm (about 1.7 million
// hexes) has no non-manifold place left, a valid mesh, a boundary whose
// topology is that of the repaired labels and of volumeToMesh of the repaired
// field, and corners on the isosurface.
TEST(Ch2bet, KeepLargestIsManifoldAndValidAtTwoAndOneMillimetre) {
    for (double size : {2.0, 1.0}) {
        const std::string name = "ch2bet_keep_largest_" + std::to_string(static_cast<int>(size)) + "mm";
        const Extracted r = extractOnly(sharedData() + "/ch2bet.nii.gz", intensity(std::nullopt, size, true));
        EXPECT_EQ(octree::countNonManifoldBlocks(r.p.labels), 0u) << name;
        std::size_t inverted = 0;
        EXPECT_TRUE(topologicallyValid(r.mesh, &inverted)) << name;
        const auto labelsTopology = octree::regionTopology(r.p.labels);
        ASSERT_EQ(labelsTopology.size(), 1u);
        const SurfaceTopology ours = meshRegionTopology(r.mesh, buildTopology(r.mesh), 1);
        EXPECT_EQ(ours.components, labelsTopology[0].components) << name;
        EXPECT_EQ(ours.euler, labelsTopology[0].euler) << name;
        const octree::Domain& repaired = r.p.extractionDomain();
        const SurfaceTopology vdb =
            vdbTopology(*sampleOnGrid(r.p.labels.grid, [&](const Vec3& x) { return repaired.value(1, x); }));
        EXPECT_EQ(ours.components, vdb.components) << name;
        EXPECT_EQ(ours.euler, vdb.euler) << name;
        const CornerFigures f = cornerDistances(r);
        print(name, f);
        std::cout << "[figures] " << name << " hexes " << r.mesh.hexCount() << ", inverted " << inverted << ", "
                  << ours.components << " boundary components, chi " << ours.euler
                  << "; volumeToMesh of the repaired field " << vdb.components << ", chi " << vdb.euler << "\n";
        expectOnTheIsosurface(name, f);
    }
}

// ch2bet against volumeToMesh of the scan's own field (not the repaired one)
// at the extraction grid's points, with and without --keep-largest (then the
// field outside the kept points is taken as outside). The repair does not
// match it exactly yet (issue 4; see docs/DESIGN.md, "Topology against
// OpenVDB"): the test holds the gap to what the repair reaches now, so a
// change that widens it fails. The boundary's topology is that of the
// repaired labels (regionTopology; the tests above check the mesh against it).
TEST(Ch2bet, TopologyNearVolumeToMeshOfTheScanAtTwoAndOneMillimetre) {
    std::map<std::string, std::vector<std::int32_t>> repairOnly;  // labels without the option, by case
    struct Bound {
        double size;
        bool keepLargest;
        bool isosurfaceTopology;
        long long components, euler;  // largest |ours - volumeToMesh| allowed
    };
    // measured (components/chi, ours against volumeToMesh's): the repair alone
    // 2 mm 323/542 against 324/544, with --keep-largest 297/492 against
    // 299/494; 1 mm 591/848 against 594/878, with --keep-largest 483/632
    // against 491/674. With --isosurface-topology all four are equal: 1 mm
    // since the deep search, 2 mm (324/544, 299/494) since its annealing.
    for (const Bound& b : {Bound{2.0, false, false, 1, 2}, Bound{2.0, true, false, 2, 2}, Bound{1.0, false, false, 3, 30},
                           Bound{1.0, true, false, 8, 42}, Bound{2.0, false, true, 0, 0}, Bound{2.0, true, true, 0, 0},
                           Bound{1.0, false, true, 0, 0}, Bound{1.0, true, true, 0, 0}}) {
        // (2 mm without --keep-largest: the repair alone is within 1 and 2;
        // the option must still change the repair's labels, checked below)
        const std::string name = "ch2bet_" + std::string(b.keepLargest ? "keep_largest_" : "") +
                                 std::to_string(static_cast<int>(b.size)) + "mm" +
                                 (b.isosurfaceTopology ? "_isosurface_topology" : "");
        pipeline::MeshSettings s = intensity(std::nullopt, b.size, b.keepLargest);
        s.isosurfaceTopology = b.isosurfaceTopology;
        QuietSink sink;
        const pipeline::Prepared p = pipeline::prepare(sharedData() + "/ch2bet.nii.gz", s, sink);
        EXPECT_EQ(octree::countNonManifoldBlocks(p.labels), 0u) << name;
        const std::string plainKey = std::to_string(b.size) + (b.keepLargest ? "k" : "");
        if (!b.isosurfaceTopology) repairOnly[plainKey] = p.labels.material;
        else EXPECT_NE(p.labels.material, repairOnly.at(plainKey)) << name << ": --isosurface-topology changed nothing";
        const auto topo = octree::regionTopology(p.labels);
        ASSERT_EQ(topo.size(), 1u) << name;
        const octree::Grid& g = p.labels.grid;
        octree::Labels kept = octree::sampleLabels(*p.domain, g);
        if (b.keepLargest) octree::keepLargestComponents(kept);
        const auto& field = p.selection->materials.at(0).field;
        auto grid = sampleOnGrid(g, [&](const Vec3& x) { return field.value(x); });
        {
            // points --keep-largest dropped are outside
            auto acc = grid->getAccessor();
            const auto [nx, ny, nz] = g.dims;
            for (int k = 0; k < nz; ++k)
                for (int j = 0; j < ny; ++j)
                    for (int i = 0; i < nx; ++i)
                        if (kept.material[g.index(i, j, k)] == 0 && acc.getValue(openvdb::Coord(i, j, k)) < 0)
                            acc.setValue(openvdb::Coord(i, j, k), 1e-3f);
        }
        const SurfaceTopology vdb = vdbTopology(*grid);
        const long long dc = static_cast<long long>(topo[0].components) - static_cast<long long>(vdb.components);
        const long long de = topo[0].euler - vdb.euler;
        std::cout << "[figures] " << name << " repaired labels " << topo[0].components << " components, chi "
                  << topo[0].euler << "; volumeToMesh of the scan's field " << vdb.components << ", chi " << vdb.euler
                  << "\n";
        EXPECT_LE(std::abs(dc), b.components) << name;
        EXPECT_LE(std::abs(de), b.euler) << name;
        if (b.isosurfaceTopology) {
            // every accepted step keeps the surface exactly, so what is off is
            // what the places the report names as not mended change
            const auto& unmended = p.facts.grid.repair.isosurfaceTopology.value().unmended;
            long long named = 0;
            for (const auto& place : unmended) named += place.place.eulerChange;
            EXPECT_EQ(named, de) << name;
            EXPECT_EQ(unmended.empty(), dc == 0 && de == 0) << name;
        }
    }
}

// The extraction of a real scan is the same for any thread count (the field is
// sampled through per-thread accessors, the repair and the classification run
// in a fixed order).
TEST(Ch2bet, SameExtractionForOneAndTwoThreads) {
    Extracted one;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        one = extractOnly(sharedData() + "/ch2bet.nii.gz", intensity(std::nullopt, 2.0, true));
    }
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    const Extracted two = extractOnly(sharedData() + "/ch2bet.nii.gz", intensity(std::nullopt, 2.0, true));
    EXPECT_EQ(one.p.labels.material, two.p.labels.material);
    EXPECT_EQ(one.mesh.hexes, two.mesh.hexes);
    EXPECT_EQ(one.mesh.nodes, two.mesh.nodes);
    EXPECT_EQ(one.mesh.nodeClass, two.mesh.nodeClass);
}

// Label maps: nodes where three materials meet (HexMesh::curves) slide along
// their curve in the optimiser instead of staying where extraction put them,
// and stay on (or within the surface tolerance of) both surfaces of the curve: f_q = f_r and, against the outside,
// the labels' union isosurface, else f_p = f_q (FieldProjector::projectToCurve).
TEST(LabelCurves, CurveNodesMoveAlongTheCurveWhereThreeMaterialsMeet) {
    using namespace isohex::vec;
    const std::string input = sharedData() + "/JHU-WhiteMatter-labels-2mm.nii.gz";
    ASSERT_TRUE(std::filesystem::exists(input)) << input;
    pipeline::MeshSettings s = labels();
    QuietSink sink;
    const pipeline::Prepared p = pipeline::prepare(input, s, sink);
    HexMesh mesh = pipeline::contour(p, s, sink);
    ASSERT_FALSE(mesh.curves.empty());
    pipeline::pillowBoundary(mesh, s, sink);
    const std::vector<Vec3> before = mesh.nodes;
    pipeline::optimize(mesh, p, s, sink);
    const octree::Domain& d = *p.domain;
    const double voxel = std::min({p.volume->spacing[0], p.volume->spacing[1], p.volume->spacing[2]});
    std::size_t curveNodes = 0, moved = 0, onCurve = 0, nearCurve = 0;
    double worst = 0;
    for (std::size_t v = 0; v < mesh.nodeCount(); ++v) {
        const NodeClass c = mesh.nodeClass[v];
        if (c.kind != NodeKind::Curve || c.id < 0) continue;
        ++curveNodes;
        const Vec3& x = mesh.nodes[v];
        if (x == before[v]) continue;
        ++moved;
        const auto [a, b, cc] = mesh.curves[static_cast<std::size_t>(c.id)];
        // each residual over its gradient: a distance to that surface, in voxels
        auto distance = [&](double f, const Vec3& g) { return std::abs(f) / std::max(1e-12, norm(g)) / voxel; };
        Vec3 gb, gc, ga;
        const double fb = d.value(b, x, &gb), fc = d.value(cc, x, &gc);
        const double first = distance(fb - fc, gb - gc);
        const double fa = a > 0 ? d.value(a, x, &ga) - fb : d.unionValue(x, &ga);
        const double second = distance(fa, a > 0 ? ga - gb : ga);
        const double off = std::max(first, second);
        worst = std::max(worst, off);
        onCurve += off <= 0.01;
        nearCurve += off <= 0.09;
    }
    std::cout << "[figures] JHU curve nodes " << curveNodes << ", moved " << moved << ", of those on their curve "
              << onCurve << ", within 0.09 voxel " << nearCurve << " (farthest " << worst << " voxel)\n";
    EXPECT_GT(curveNodes, 1000u);
    EXPECT_GT(moved, curveNodes / 4);
    // Released to untangle (validity before fidelity) may stay off; few. The
    // worst-hex pass's slack rounds may leave a curve node off its curve by
    // the surface tolerance (0.09 voxel), as they do surface nodes; the mean
    // rounds after them put most of those they visit back on it.
    EXPECT_GE(nearCurve, moved * 95 / 100);
    EXPECT_GE(onCurve, moved * 90 / 100);
}

// A label map whose interface runs through grid points. The two_materials
// phantom splits its ball at x = 31.5 (half-way between voxel columns 31 and
// 32; samples/make_phantoms.py, unit spacing, origin 0), and a 1.5-voxel grid
// has points on that plane, where the two labels' fields are both exactly 0.5.
// The grid edges ending there used to count as having no crossing, so the
// interface went to the cell midpoint x = 30.75, where label 1's field is
// flat and nothing could project it back: each half of the ball was 5% off
// its volume. The interface must lie on the plane and each label keep its
// volume; and a node moved back into that flat place must count as off the
// surface in the report (the projection cannot move it, and its own position
// used to be taken as the answer: distance 0).
TEST(Labels, InterfaceThroughGridPointsStaysOnIt) {
    pipeline::MeshSettings s = labels();
    s.size = 1.5;
    const Extracted r = extractOnly(phantoms() + "/two_materials.nii.gz", s);
    ASSERT_TRUE(topologicallyValid(r.mesh));
    std::int32_t interface = -1;
    for (std::size_t k = 0; k < r.mesh.surfaces.size(); ++k)
        if (r.mesh.surfaces[k].inside == 1 && r.mesh.surfaces[k].outside == 2) interface = static_cast<std::int32_t>(k);
    ASSERT_GE(interface, 0);
    std::size_t onInterface = 0;
    double farthest = 0;
    Index someInterfaceNode = -1;
    for (std::size_t v = 0; v < r.mesh.nodeCount(); ++v) {
        const NodeClass c = r.mesh.nodeClass[v];
        if (c.kind != NodeKind::Surface || c.id != interface) continue;
        ++onInterface;
        farthest = std::max(farthest, std::abs(r.mesh.nodes[v][0] - 31.5));
        someInterfaceNode = static_cast<Index>(v);
    }
    std::cout << "[figures] two_materials at 1.5 voxels: " << onInterface
              << " nodes on the 1|2 interface, farthest from x = 31.5: " << farthest << " voxel\n";
    EXPECT_GT(onInterface, 100u);
    EXPECT_LE(farthest, 0.1);

    std::map<std::int32_t, double> meshVolume;
    for (std::size_t h = 0; h < r.mesh.hexCount(); ++h)
        meshVolume[r.mesh.material[h]] += hexVolume(hexCoords(r.mesh, static_cast<Index>(h)));
    for (const auto& m : r.p.selection->materials) {
        const double iso = pipeline::isosurfaceVolume(m.field.grid());
        std::cout << "[figures] two_materials label " << m.id << ": mesh " << meshVolume[m.id] << ", 0.5-isosurface "
                  << iso << " (" << 100 * (meshVolume[m.id] - iso) / iso << "%)\n";
        EXPECT_LT(std::abs(meshVolume[m.id] - iso) / iso, 0.02) << "label " << m.id;
    }

    // Every grid point takes the label whose field is lowest there. The
    // nearest voxel alone is not enough: at a point shared by eight voxels it
    // is one of them, whatever the other seven are, and grid edges from such a
    // point had no crossing on them (the vertices stayed where the fields are
    // flat, about a voxel off the ball: 47 surface nodes after optimisation).
    const octree::Labels sampled = octree::sampleLabels(*r.p.domain, r.p.labels.grid);
    const auto& d = sampled.grid.dims;
    std::size_t disagree = 0, labelled = 0;
    for (int k = 0; k < d[2]; ++k)
        for (int j = 0; j < d[1]; ++j)
            for (int i = 0; i < d[0]; ++i) {
                const std::int32_t a = sampled.material[sampled.grid.index(i, j, k)];
                if (a <= 0) continue;
                ++labelled;
                const Vec3 x = sampled.grid.point(i, j, k);
                const double fa = r.p.domain->value(a, x);
                for (const auto& m : r.p.selection->materials)
                    if (m.id != a && r.p.domain->value(m.id, x) < fa) {
                        ++disagree;
                        break;
                    }
            }
    std::cout << "[figures] two_materials grid points with a label whose field is not the lowest: " << disagree
              << " of " << labelled << "\n";
    EXPECT_GT(labelled, 10000u);
    EXPECT_EQ(disagree, 0u);

    const pipeline::FidelityResult before = pipeline::fidelity(r.mesh, r.p);
    HexMesh moved = r.mesh;
    moved.nodes[static_cast<std::size_t>(someInterfaceNode)][0] = 30.75;
    const pipeline::FidelityResult after = pipeline::fidelity(moved, r.p);
    EXPECT_EQ(after.boundary.notProjected, before.boundary.notProjected + 1);
}

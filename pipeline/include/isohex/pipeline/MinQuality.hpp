#pragma once
// The certified minimum quality (--min-quality Q): the means that lift the
// hexes still below Q after the optimiser (bounded boundary relaxation), and
// the certificate of the mesh as written: the target, the smallest scaled
// Jacobian reached, the mean and histogram, and each place left below Q with
// its position, material and cause.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Quality.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/pipeline/LocalFeatures.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/StageSink.hpp"
#include "isohex/smoothing/SurfaceProjector.hpp"

namespace isohex::pipeline {

// Why a hex stays below the target, read from its nodes' classes (or, when
// the optimiser did not run, that).
enum class BelowCause {
    LabelJunction,   // a node on a curve where three materials (or two and the outside) meet
    ThinFeature,     // every node on a surface: the hex spans a feature thinner than an element
    BoundaryPinned,  // surface nodes held on the isosurface (within --max-deviation)
    Interior,        // interior nodes only: no placement the node moves found lifts it
    NotOptimised,    // --no-optimize: the hexes as extracted and pillowed, no node moved
};
// "label junction", "feature thinner than an element", ...: the report's and
// the messages' wording.
const char* causeText(BelowCause cause);

// Why hex h stays below the target, from its nodes' classes (a curve or
// fixed node: a label junction; every node on a surface: a thin feature; some:
// pinned to the boundary; none: interior).
BelowCause causeOf(const HexMesh& mesh, Index h);

// One hex left below the target.
struct BelowPlace {
    Vec3 at{};                  // its centre, world coordinates
    std::int32_t material = 0;
    double scaledJacobian = 0;  // 0 for a degenerate hex
    BelowCause cause = BelowCause::Interior;
    std::optional<LocalShape> shape;  // the labels' shape next to it, when the labels were given
};

// The places the report lists (worst first); the count covers them all.
inline constexpr std::size_t kMaxPlacesListed = 200;

// Bounded boundary relaxation: the max-min pass once more on the hexes below
// the target, surface nodes free within --max-deviation of their isosurface,
// curve nodes of their curve, junction nodes of every surface around them.
struct RelaxationResult {
    double target = 0;  // the hexes below it were lifted (aimed kRelaxationMargin above it)
    double maxDeviationVoxels = 0;
    // surface nodes the relaxation took farther off their surface, beyond the surface tolerance
    std::size_t nodesOff = 0;
    // curve and junction nodes it took farther off their curve or surfaces, beyond the surface tolerance
    std::size_t curveNodesOff = 0;
    double largestDeviationVoxels = 0;  // the farthest of the nodes it took farther off
    std::size_t nodesMoved = 0;
    double minBefore = 0, minAfter = 0;
    std::size_t belowBefore = 0, belowAfter = 0;  // hexes below the target (Q, not the aim above it)
    int passes = 1;          // max-min passes run (kRelaxationFirstSteps)
    double firstStep = 0;    // the kept pass's first step, in local edge lengths
    std::size_t regionHexes = 0;  // hexes of the submesh it worked on (MinQuality.cpp, relaxRegion)
    double seconds = 0;
};

struct QualityCertificate {
    double target = 0;            // Q
    bool defaultTarget = true;    // Q is the default for the input's kind (no --min-quality)
    double achieved = 0;          // the smallest scaled Jacobian (0 when a hex is degenerate)
    double mean = 0;
    std::array<std::size_t, 11> histogram{};  // over kScaledJacobianBins
    bool certified = false;       // achieved >= target and no hex inverted or degenerate
    std::size_t hexesBelow = 0;   // below the target, inverted and degenerate included
    std::vector<BelowPlace> places;  // the worst kMaxPlacesListed of them
    std::optional<double> worstHexTarget;  // the max-min pass's target, when raised to Q
    std::optional<RelaxationResult> relaxation;  // when it ran
    // every hex below the target by the labels' shape next to it (LocalShape
    // order), when the labels were given
    std::optional<std::array<std::size_t, kLocalShapes>> belowByShape;
};

// The default Q, chosen by measurement (VTK on the written files;
// bench/RESULTS.md, "Feature removal and retries optimise a neighbourhood"):
// - an intensity scan (CT, MRI, a smooth field): 0.3, which skull_ct, ch2bet
//   at 1-4 mm and the phantoms reach with the relaxation and feature removal;
// - a label map: 0.3 as well, which the JHU labels reach at their default
//   level and at the bench's 9 sizes with the relaxation free to a voxel
//   (kDefaultMaxDeviationLabelMap), started again from other steps at
//   junctions (kRelaxationFirstSteps), and feature removal, junction points
//   included (6 mm: 0.235 without them, where four labels meet at nodes
//   shared by 15 hexes; 0.306 with them);
// - a closed triangle surface: 0.5, which every surface of the bench and test
//   data reaches with the max-min pass aimed at it; with the sheet method
//   0.2, since its volume fit trades the worst hexes for volume (femur.off
//   ends at 0.284 with 0.5 asked of the max-min pass);
// - a scan or label map meshed with --no-optimize or --fix-boundary: 0,
//   since those runs ask for the mesh without the means that reach 0.3;
// - a mesh of any origin (insert-sheet): 0, no inverted or degenerate hex.
inline constexpr double kDefaultMinQualityIntensity = 0.3;
inline constexpr double kDefaultMinQualityLabelMap = 0.3;
inline constexpr double kDefaultMinQualityWithoutMeans = 0.0;
inline constexpr double kDefaultMinQualityAnyMesh = 0.0;
// The relaxation aims this far above Q: a max-min pass stops when its worst
// hex reaches its target, and one aimed at Q exactly left ch2bet at 2 mm one
// hex at 0.2994 against a Q of 0.3.
inline constexpr double kRelaxationMargin = 0.01;
// The relaxation's compass search starts from the first of these steps (in
// local edge lengths; the max-min pass's own), and while hexes at junctions
// of labels stay below Q it starts again from the same nodes with the next,
// keeping the best: there its result hangs on the first step. On the JHU
// labels at 4 mm one step left 0.296 and the three reach 0.304; every size of
// the bench but 6 mm then reaches 0.3 (6 mm: 0.191 -> 0.235). A scan's hexes
// below Q are not at junctions and get the one pass.
inline constexpr std::array<double, 3> kRelaxationFirstSteps = {0.25, 0.125, 0.5};
// The max-min pass's target when neither --worst-hex-target nor a higher
// --min-quality sets it, and the second target it aims at from there once
// every hex has reached the first (stretchTargetFor).
inline constexpr double kDefaultWorstHexTarget = 0.3;
inline constexpr double kStretchTarget = 0.5;
inline constexpr double kDefaultMinQualitySurface = 0.5;
inline constexpr double kDefaultMinQualitySheetMethod = 0.2;
// The default --max-deviation in voxels: half a voxel for an intensity
// scan, whose isosurface is interpolated within a voxel; a whole voxel for a
// label map, whose interfaces are known only to the voxel each label fills.
// On the JHU labels a voxel reaches 0.3 at 8 of the bench's 9 sizes, half a
// voxel at 2, with at most 4% more interface nodes beyond 0.1 voxel, the mean
// boundary distance within 0.005 mm and the volume change smaller (sizes 3,
// 4.5 and 5 mm).
inline constexpr double kDefaultMaxDeviation = 0.5;
inline constexpr double kDefaultMaxDeviationLabelMap = 1.0;

// Q for `input` under `settings`: settings.minQuality, else the default of the
// input's kind.
double minQualityFor(const std::string& input, const MeshSettings& settings);

// How far, in voxels, the boundary relaxation may take a node off its
// surface: settings.maxDeviation, else the default of the input's kind.
double maxDeviationFor(const std::string& input, const MeshSettings& settings);

// The target the max-min pass aims at: the larger of its own and Q.
double worstHexTargetFor(const std::string& input, const MeshSettings& settings);

// The second target of the max-min pass (0: none): kStretchTarget where the
// user set neither --worst-hex-target nor --min-quality and the first target
// is lower (scans and label maps; the dual method, boundary free). Where the
// first pass leaves every hex at or above its target, a second pass aims at
// this one and is kept only if it lifts the minimum (stretchWorstHexes):
// smooth scans reach 0.5 (skull_ct 0.313 -> 0.501) while scans with hexes
// stuck below 0.3 are not slowed by a pass that cannot help them.
double stretchTargetFor(const std::string& input, const MeshSettings& settings);

// Surface nodes may leave their surface by at most `maxDeviation` (world
// units) to lift the hexes below q (aimed kRelaxationMargin above it); only
// the nodes of those hexes move, then, in mean rounds, the nodes next to
// them (no hex below the aim or below its value); from each of
// kRelaxationFirstSteps while hexes at label junctions stay below q, the
// best kept. `voxel` converts the figures to voxels for the report;
// `tolerance` (world units) is the distance a node off its surface counts from.
// `sj`: scaledJacobians(mesh) as the mesh is (the caller has it already).
RelaxationResult relaxBoundary(HexMesh& mesh, const std::vector<double>& sj, const smoothing::SurfaceProjector& projector,
                               double q, double maxDeviation, double tolerance, double voxel);

// Whether a run's settings let the boundary relax (the optimiser with its
// worst-hex pass, the dual method, surface nodes free): where not, stage
// "relax" never runs and --max-deviation has nothing to bound.
bool relaxesBoundary(const MeshSettings& settings);

// Stage "relax" of the dual pipeline, after the retries: relaxBoundary on the
// scan's isosurfaces when hexes are still below Q and --max-deviation is
// beyond the surface tolerance (none with --no-optimize, --fix-boundary or
// --no-worst-hex-pass); none when it had nothing to do.
std::optional<RelaxationResult> relaxToMinQuality(HexMesh& mesh, const Prepared& p, const MeshSettings& settings,
                                                  StageSink& sink);

// The certificate of `mesh` against `target`; with `local`, each hex below
// it also by the shape of the labels next to it. `optimised` false (no node
// was moved: --no-optimize): every place's cause is NotOptimised instead of
// one read from its nodes' classes.
QualityCertificate certifyQuality(const HexMesh& mesh, double target, const LocalFeatures* local = nullptr,
                                  bool optimised = true);

// Whether certifyQuality counts a scaled Jacobian as below `target`: below
// it, not positive, or Verdict's degenerate value.
inline bool belowTarget(double sj, double target) { return scaledJacobianCollapsed(sj) || !(sj > 0) || sj < target; }

// One line per place (at most `lines`, then how many more): position,
// material, value and cause.
std::string describePlaces(const QualityCertificate& c, std::size_t lines);

}  // namespace isohex::pipeline

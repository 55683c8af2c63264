#pragma once
// The optimisation stage: untangling and mean-ratio optimisation with surface
// nodes kept on the isosurface (smoothing::optimizeMesh through a
// FieldProjector), then the max-min pass on the hexes it leaves poor.
#include <cstdint>
#include <optional>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/StageSink.hpp"
#include "isohex/smoothing/BoundaryQuads.hpp"
#include "isohex/smoothing/Optimize.hpp"
#include "isohex/smoothing/WorstHexes.hpp"

namespace isohex::pipeline {

struct WorstHexPassResult {
    smoothing::WorstHexOptions options;
    smoothing::WorstHexResult result;
    double seconds = 0;
    // The surface tolerance in voxels the slack came from (the dual pipeline only).
    std::optional<double> surfaceToleranceVoxels;
};

// The max-min pass on the hexes the optimiser left below `target`
// (smoothing/WorstHexes.hpp), timed. Surface nodes move only with a
// projector; `topo` (buildTopology(mesh)) saves building it again. `slack`:
// how far (world units) surface nodes may end off their surface
// (smoothing::WorstHexOptions::surfaceSlack). `progress` hears the pass's
// ("worst_hexes").
WorstHexPassResult worstHexPass(HexMesh& mesh, const smoothing::SurfaceProjector* projector, double target,
                                double slack = 0, const Topology* topo = nullptr, const Progress& progress = {});

// The max-min pass aimed at a second, higher target from where the first
// left every hex at or above its own (stretchWorstHexes).
struct StretchResult {
    double target = 0;
    bool kept = false;                       // false: every node was put back
    double minBefore = 0, minAfter = 0;      // smallest scaled Jacobian before and after the pass
    double meanBefore = 0, meanAfter = 0;    // mean scaled Jacobian before and after the pass
    WorstHexPassResult pass;
};

// How much the mean scaled Jacobian may fall for a second pass to be kept: a
// higher minimum is not bought with the mean (skull_ct: 0.313 -> 0.501 with
// the mean 0.8506 -> 0.8537; the ladder's rule, docs/DESIGN.md).
inline constexpr double kStretchMeanLoss = 0.005;

// The max-min pass aimed at `target` from the mesh as it is (`slack` as for
// worstHexPass); kept when the smallest scaled Jacobian rises, no hex is
// inverted and the mean falls by at most kStretchMeanLoss, otherwise every
// node goes back where it was.
StretchResult stretchWorstHexes(HexMesh& mesh, const smoothing::SurfaceProjector* projector, double target,
                                double slack = 0, const Progress& progress = {});

// stretchWorstHexes aimed at `stretch` where it applies: the first pass
// (aimed at `firstTarget`) reached `reached` >= firstTarget, and `stretch` is
// above both; otherwise nothing is done.
std::optional<StretchResult> stretchIfReached(HexMesh& mesh, const smoothing::SurfaceProjector* projector,
                                              double firstTarget, double reached, double stretch, double slack = 0,
                                              const Progress& progress = {});

struct OptimizeResult {
    bool enabled = false;  // settings.optimize; nothing else is set without it
    bool fixBoundary = false;
    smoothing::SmoothingResult smoothingResult;
    std::optional<WorstHexPassResult> worstHexes;  // with settings.worstHexPass
    std::optional<StretchResult> stretch;          // where the pass reached its target and a second one applies
};

// Stage "boundary_quads" of compare's protocol (the seed's): the boundary and
// interface quads smoothed on the scan's isosurfaces before the boundary is
// fixed (smoothing::smoothBoundaryQuads).
smoothing::BoundaryQuadResult smoothBoundaryOnIsosurface(HexMesh& mesh, const Prepared& p, StageSink& sink);

// What a run of the optimiser covers. A neighbourhood (LocalRetry.hpp) is
// mostly nodes already optimised around a few new ones: its mean-ratio
// sweeps stop when no node is active, not on a fraction of its summed
// objective (which the optimised nodes dominate, so the sweeps stopped after
// one with the new nodes barely moved).
enum class OptimizeScope : std::uint8_t { Whole, Neighbourhood };

// Stage "optimize". Unless `warnLeftInverted` is false, a warning names the
// hexes still inverted after it.
OptimizeResult optimize(HexMesh& mesh, const Prepared& p, const MeshSettings& settings, StageSink& sink,
                        bool warnLeftInverted = true, OptimizeScope scope = OptimizeScope::Whole);

}  // namespace isohex::pipeline

#pragma once
// isohex estimate: a mesh's size, peak memory and time before any of it is
// built (the scan loaded and selected and the grid chosen; no sampling,
// repair, contouring or optimisation), so a scheduler can ask for the CPUs,
// memory and time a job needs.
#include <cstddef>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "isohex/core/MeshIO.hpp"
#include "isohex/pipeline/MeshSettings.hpp"
#include "isohex/pipeline/Part.hpp"
#include "isohex/pipeline/Prepare.hpp"
#include "isohex/pipeline/StageSink.hpp"

namespace isohex::pipeline {

// With settings.part (--part K/N) the estimate is of that part's job: the
// hexes, memory and time of its window (its slab and the ghost layers, which
// it builds before keeping its own hexes), and the hexes it keeps.
struct MeshEstimate {
    double hexes = 0;             // expected hexes the run builds (the finished mesh; a part's window)
    std::size_t gridPoints = 0;   // points of the element grid
    double loadedBytes = 0;       // peak resident memory after loading and selecting
    double peakBytes = 0;         // expected peak resident memory of `isohex mesh`
    double cpuSeconds = 0;        // expected CPU time (user + system) of `isohex mesh`
    double wallSeconds = 0;       // expected wall time with `threads` threads
    int threads = 1;              // the threads the wall time is for
    bool threadsChosen = false;   // threads were chosen by the estimate (none asked for)
    std::optional<PartWindow> part;  // with settings.part: its window of the whole grid
    double ownHexes = 0;             // with settings.part: the hexes of its own slab (what it writes)
};

// The time model, fitted by bench/fit_time_model.py to bench/RESULTS.md's
// runs (section "The time model of `isohex estimate`": 8 inputs and ch2bet at
// 8 element sizes from 12 k to 5 M hexes, --threads 2): CPU seconds (user +
// system) against the finished mesh's hexes h and the loaded scan's voxels V,
// least squares of log(CPU): 0.000304 h^0.840 + 4.01e-7 V, every run within
// a factor 1.93 of it (13 of 16 within 1.3; the voxel term is loading,
// selection and the octree, which on ch2bet at 6 mm are most of the time).
// Without optimisation (the voxel baseline's rows): 0.137 s + 1.92 us per hex
// + 0.293 us per voxel, within a factor 1.52. Wall time: 0.37 s that does not
// spread over threads plus the rest spread at the measured efficiency (CPU /
// wall = 1.85 at 2 threads, i.e. each thread past the first adds 0.85);
// beyond 2 threads that is an extrapolation, not a measurement. The runs were
// all with the sheet: without it (--no-pillow) the optimiser works harder on
// some inputs (bench: 0.8 to 10 times the CPU time of the same input with the
// sheet), which the model does not know.
struct TimeModel {
    double cpuCoefficient = 0.000304, cpuExponent = 0.840, cpuPerVoxel = 4.01e-7;
    double noOptimizeSeconds = 0.137, noOptimizePerHex = 1.92e-6, noOptimizePerVoxel = 2.93e-7;
    double startSeconds = 0.37;
    double extraThreadEfficiency = 0.85;
};

// CPU seconds of a default run (or one without optimisation) making `hexes`
// hexes from a scan of `voxels` voxels.
double expectedCpuSeconds(double hexes, double voxels, const MeshSettings& settings, const TimeModel& model = {});
// Bytes of a mesh file of `hexes` hexes in `format`: bytes per hex measured by
// bench/output_sizes.py on six inputs with default options (the middle of
// each format's range; every input within 2% for .vtu, 6% .exo, 10% .inp,
// 13% .msh, 14% .mesh).
double expectedOutputBytes(double hexes, io::Format format);
// Wall seconds of that CPU time on `threads` threads.
double expectedWallSeconds(double cpuSeconds, int threads, const TimeModel& model = {});
// The fewest threads, up to maxThreads, whose expected wall time is at most
// targetSeconds (maxThreads when none is).
int chooseThreads(double cpuSeconds, int maxThreads, double targetSeconds, const TimeModel& model = {});

struct EstimateOptions {
    int threads = 0;             // the job's threads; 0: chosen (chooseThreads)
    int maxThreads = 8;          // the most threads chosen
    double targetSeconds = 120;  // the wall time the chosen threads aim at
};

// Loads and selects `input` and chooses its grid (prepareGrid), then
// estimates the mesh. Throws like prepare() on bad input or settings, and a
// SettingError for the sheet method (which has no grid before meshing).
MeshEstimate estimateMesh(const std::string& input, const MeshSettings& settings, const EstimateOptions& options,
                          StageSink& sink, PreparedFacts* facts = nullptr);

// The estimate as isohex estimate prints it: input, element size and grid,
// hexes, memory in MB, seconds, threads, and the model's stated accuracy;
// with a part also "part" (index, count, axis, own and window layers, own hexes).
nlohmann::json toJson(const MeshEstimate& e, const PreparedFacts& facts);

}  // namespace isohex::pipeline

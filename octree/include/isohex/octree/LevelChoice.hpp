#pragma once
// Choosing the grid: the coarsest uniform level that keeps the topology and
// volume of the finest one (LBIE's starting level), with LBIE's per-cell
// tests of whether coarse cells may replace their children.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "isohex/octree/Domain.hpp"
#include "isohex/octree/Grid.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/Regions.hpp"

namespace isohex::octree {

// LBIE's test of whether coarse cells (2 fine steps wide) may replace their 8
// children: on the fine labels, a coarse edge whose ends agree must not change
// material at its midpoint, a coarse face or cell whose corners all agree must
// not differ at its centre, and no coarse face or cell may carry an ambiguous
// (diagonal) pattern. Returns the number of coarse cells that fail.
std::size_t lbieFailures(const Labels& fine);

// Why the next coarser level was not taken.
struct LevelRejection {
    int level = 0;           // the level not taken
    bool cellTests = false;  // its cells failed LBIE's tests (`why` counts them)
    std::string why;         // "10112 coarse cells fail ...", "changes the volume by 6.3% (...)"
    // "level 1: 10112 coarse cells fail ..." or "level 2 changes the volume by ..."
    std::string note() const;
};

struct LevelChoice {
    int level = 0;                        // grid step = 2^level base steps
    Grid grid;
    std::vector<RegionTopology> topology; // at the chosen level (after repair)
    std::vector<RegionTopology> reference;// at level 0 (after repair)
    double volumeChange = 0;              // relative change of labelled volume vs level 0
    std::optional<LevelRejection> rejected;  // none when the coarsest level tried was taken
};

struct LevelOptions {
    int maxLevel = 6;
    double maxVolumeChange = 0.05;        // a coarser level must keep the labelled volume within this
    std::size_t minPoints = 64;           // and keep at least this many labelled points per material
    bool cellTests = true;                // also require LBIE's per-cell topology tests to pass
};

// The coarsest level whose repaired regions have the same components and Euler
// characteristics as the finest (base) grid and whose labelled volume is
// within maxVolumeChange: the LBIE starting level chosen by topology.
LevelChoice chooseLevel(const Domain& domain, const Grid& base, const LevelOptions& opt = {});

}  // namespace isohex::octree

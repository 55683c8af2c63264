#pragma once
// The connected regions of grid points: which points of a material form one
// region (union-find over the grid), and the topology of each material's
// boundary (components and Euler characteristic).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/octree/Labels.hpp"

namespace isohex::octree {

// Which grid points count as neighbours.
enum class Adjacency {
    Face,  // 6-adjacency: the points differ by one step along one axis
    Full,  // 26-adjacency: also along an edge or at a corner of their cubes
};

// Union-find over the grid points (by index) in which two points are in one
// set when a chain of neighbours (under `adjacency`) of their own non-zero
// material joins them. Background points stay singletons. Each set's root
// is its smallest point index (DisjointSets' rule), so the sets and their
// roots depend on the labels only. Callers may unite further (e.g. the parts
// a polygoniser's surface joins). Grids up to 2^32 points.
DisjointSets<std::uint32_t> materialRegions(const Labels& labels, Adjacency adjacency);

// Topology of each material region's boundary: connected components and
// Euler characteristic (a closed surface of genus g per component has chi = 2 - 2g).
// The boundary is that of the union of the closed cubes around the
// material's points.
struct RegionTopology {
    std::int32_t material = 0;
    std::size_t components = 0;
    long long euler = 0;
    std::size_t points = 0;              // grid points in the region
    bool operator==(const RegionTopology&) const = default;
};
// One entry per material present, ascending material.
std::vector<RegionTopology> regionTopology(const Labels& labels);
// One line for messages: each material's components and Euler characteristic.
std::string describe(const std::vector<RegionTopology>& t);

}  // namespace isohex::octree

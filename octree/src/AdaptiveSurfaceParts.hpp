#pragma once
// The pieces of contourAdaptive (AdaptiveSurface.hpp): finding leaves by
// position, placing the nodes of an assembled tree and the checks that ask
// for more refinement.
#include <array>
#include <cstdint>
#include <vector>

#include "isohex/octree/AdaptiveHexes.hpp"
#include "isohex/octree/AdaptiveSurface.hpp"
#include "isohex/octree/Domain.hpp"
#include "isohex/octree/RefinementTree.hpp"

namespace isohex::octree {

// Positions in half key steps (2 x NodeKey coordinates), so the centres
// around a node (its key +-1/2) are integers.
using HalfKey = std::array<std::int64_t, 3>;

struct Leaf {
    int level = -1;  // -1: outside the tree
    std::array<int, 3> cell{0, 0, 0};
};

class LeafLocator {
public:
    explicit LeafLocator(const RefinementTree& tree);
    // The leaf holding the point at `h` (not on a cell face).
    Leaf at(const HalfKey& h) const;
    // The highest level of the eight leaves around a node.
    int levelAround(NodeKey key) const;

private:
    const RefinementTree& tree_;
    std::vector<std::int64_t> side_;  // per level: cell side in half key steps
};

// A boundary or interface quad of the assembled mesh.
struct SurfaceQuad {
    std::array<Index, 4> nodes;
    std::array<Index, 2> hex{kNone, kNone};  // hex[1]: kNone on the boundary
    std::int32_t surface = -1;               // index into HexMesh::surfaces, -1 for a pair it has none for
    std::int32_t material = 0;               // the material whose zero set the quad approximates
};

// An assembled tree with its nodes placed.
struct PlacedMesh {
    AdaptiveMesh a;
    std::vector<Vec3> lattice;           // per node: its lattice position
    std::vector<std::uint8_t> moved;     // per node: 1 unless it is the uniform mesh's node
    std::vector<std::uint8_t> junction;  // per node: on quads of two surfaces or an unknown one
    std::vector<SurfaceQuad> quads;
};

// Numbers and places the nodes of `leaves` (see AdaptiveSurface.hpp).
PlacedMesh placeAdaptive(const LeafHexes& leaves, const LeafLocator& locate, const Labels& labels,
                         const UniformNodes& uniformAt, const HexMesh& uniform, const Domain& domain);

// What the checks found, per RefineReason: nodes whose leaves around should
// be refined, and hexes whose own leaf should be.
struct Problems {
    std::array<std::vector<Index>, kRefineReasons> nodes;
    std::array<std::vector<Index>, kRefineReasons> hexes;
};

// The checks of AdaptiveSurface.hpp; `tolerance` in world units.
Problems findProblems(const PlacedMesh& p, const Domain& domain, double tolerance);

}  // namespace isohex::octree

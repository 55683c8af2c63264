#pragma once
// What the element grid's labels look like next to a hex left below the
// certified minimum, and the features finer than one element found there:
// a speck (a few grid points of a material inside another), a pocket (a few
// points of background or another material enclosed), a strand or tunnel
// one point wide. Read on the repaired labels the hexes were contoured from
// (a dual-contouring hex sits on one labelled grid point; a sheet hex next
// to one).
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/octree/Domain.hpp"
#include "isohex/octree/Labels.hpp"
#include "isohex/octree/RepairedDomain.hpp"

namespace isohex::pipeline {

// The local shape of the labels next to a hex, most specific first.
enum class LocalShape {
    Speck,        // a component of at most kFeaturePoints points of a material
    Pocket,       // the same of the background (a cavity)
    Strand,       // a material one grid point wide along two axes
    Tunnel,       // the background (or another material) one point wide along two axes
    ThinSheet,    // a material or gap one grid point thick along one axis
    RepairSite,   // a grid point the non-manifold repair (or --keep-largest) changed
    TripleLine,   // three or more labels (the outside counted) in the 3x3x3 block
    Boundary,     // a smooth boundary: the surface nodes' deviation bound holds it
    Interior,     // one label only around it
};
inline constexpr std::size_t kLocalShapes = 9;
// "speck", "pocket", ...: the report's wording.
const char* shapeText(LocalShape shape);

// A component at most this many grid points is a feature finer than an element.
inline constexpr std::size_t kFeaturePoints = 8;

// One feature finer than an element: its grid points and the label that
// replaces them (the most common 6-neighbour label outside it).
struct FineFeature {
    LocalShape shape = LocalShape::Speck;
    std::int32_t material = 0, replacedBy = 0;
    std::vector<std::size_t> points;  // grid point indices, sorted
    Vec3 at{};                        // the points' mean, world coordinates
    double volume = 0;                // points x cell volume, world units cubed
};

// Reads the labels around hexes. `repaired` (optional) marks the repair sites.
class LocalFeatures {
public:
    LocalFeatures(const octree::Labels& labels, const octree::RepairedDomain* repaired);
    // The shape next to the hex centred at `centre` (world coordinates).
    LocalShape shapeAt(const Vec3& centre) const;
    // The features finer than an element next to `centre`: specks and pockets
    // (components of at most kFeaturePoints points), strands and tunnels (runs
    // one point wide of at most kFeaturePoints points). A thin sheet is left:
    // removing it would open a hole.
    std::vector<FineFeature> featuresAt(const Vec3& centre) const;

private:
    const octree::Labels& labels_;
    const octree::RepairedDomain* repaired_;
    std::array<std::array<double, 3>, 3> toGrid_{};
    double cellVolume_ = 0;
    std::array<int, 3> nearestPoint(const Vec3& x) const;
    // the points of p's label joined to p through 6-neighbours (with
    // `thinOnly`, only those one point wide along two axes: a strand or
    // tunnel); empty when they reach the grid's border, go farther than
    // `radius` from `centre` or number more than kFeaturePoints
    std::vector<std::size_t> flood(std::size_t p, const std::array<int, 3>& centre, int radius, bool thinOnly) const;
    int thinAxes(int i, int j, int k) const;  // axes along which both 6-neighbours have another label
    FineFeature describe(LocalShape shape, std::vector<std::size_t> points) const;
};

}  // namespace isohex::pipeline

#include "isohex/pipeline/AdaptiveContour.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "isohex/core/HexCell.hpp"
#include "isohex/octree/AdaptiveSurface.hpp"
#include "isohex/pipeline/Sizing.hpp"

namespace isohex::pipeline {

namespace {

// Shortest and longest hex edge (each edge counted from every hex it is in).
void edgeRange(const HexMesh& m, double& shortest, double& longest) {
    static constexpr int edge[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                        {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    shortest = std::numeric_limits<double>::infinity();
    longest = 0;
    for (const Hex& h : m.hexes)
        for (const auto& e : edge) {
            const Vec3& a = m.nodes[static_cast<std::size_t>(h[e[0]])];
            const Vec3& b = m.nodes[static_cast<std::size_t>(h[e[1]])];
            const double d = std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                                       (a[2] - b[2]) * (a[2] - b[2]));
            shortest = std::min(shortest, d);
            longest = std::max(longest, d);
        }
    if (m.hexes.empty()) shortest = 0;
}

}  // namespace

HexMesh coarsenContour(const Prepared& p, const HexMesh& uniform, const MeshSettings& settings, AdaptiveFacts& facts) {
    octree::AdaptiveSurfaceSettings as;
    as.maxLevel = sizingTopLevel(p, settings, facts.sizing);
    as.deviation = settings.adaptiveDeviation;
    as.grading = settings.grading;
    const octree::RequestMasks sizing = sizingRequests(p, settings, as.maxLevel, facts.sizing);
    octree::AdaptiveSurfaceResult r = octree::contourAdaptive(p.labels, p.extractionDomain(), uniform, as, sizing);
    const octree::RefinementTree& tree = r.tree;
    facts.topLevel = tree.top();
    facts.uniformHexes = uniform.hexCount();
    facts.hexesPerLevel = r.mesh.hexesPerLevel;
    facts.hexesPerForm = r.mesh.hexesPerForm;
    facts.leavesPerForm = r.mesh.leavesPerForm;
    facts.cellsAtLabelChanges = r.criterionCells.size() > 1 ? r.criterionCells[1] : 0;
    facts.cellsBySurface.assign(r.criterionCells.begin() + 1, r.criterionCells.end());
    for (const auto& round : r.rounds) facts.cellsByCheck.push_back(round.cells);
    facts.unresolved = r.unresolved;
    facts.cellsForBalance.assign(tree.promoted.begin() + 1, tree.promoted.end());
    facts.cellsForGrading.assign(tree.graded.begin() + 1, tree.graded.end());
    facts.cellsRequested.assign(tree.requested.begin() + 1, tree.requested.end());
    facts.grading = settings.grading;
    facts.hexLevel = std::move(r.mesh.hexLevel);
    edgeRange(r.mesh.mesh, facts.smallestEdge, facts.largestEdge);
    facts.treeHexes = r.mesh.mesh.hexCount();
    return std::move(r.mesh.mesh);
}

bool keepTree(const HexMesh& tree, const HexMesh& uniform, const MeshSettings& settings, AdaptiveFacts& facts) {
    if (settings.keepTree ||
        static_cast<double>(tree.hexCount()) <= kTreeKeptAtMost * static_cast<double>(uniform.hexCount())) return true;
    facts.uniformKept = true;
    facts.hexLevel.assign(uniform.hexCount(), 0);
    facts.hexesPerLevel = {uniform.hexCount()};
    facts.hexesPerForm = {{uniform.hexCount(), 0, 0, 0, 0, 0}};
    edgeRange(uniform, facts.smallestEdge, facts.largestEdge);
    return false;
}

}  // namespace isohex::pipeline

#include "isohex/core/Collapse.hpp"

#include <algorithm>
#include <numeric>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "SurfaceEdges.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/Validate.hpp"
#include "isohex/core/VecMath.hpp"

namespace isohex {

namespace {

using namespace vec;

// What becomes of each node: target[v] is the node v merges into (itself if
// it stays); per sheet edge, in sheet order, the position and class of the
// node its two ends become.
struct CollapsePlan {
    std::vector<Index> target;
    std::vector<Vec3> newPos;
    std::vector<NodeClass> newClass;
};

// Decides each sheet edge's fate: an end on a surface or curve stays where it
// is (two such ends must be of one surface and the edge must lie in it: they
// meet half-way), two interior ends meet half-way. Throws where the collapse
// would merge or pinch surfaces, or the sheet touches itself.
CollapsePlan planEdgeCollapses(const HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet) {
    const std::size_t N = mesh.nodeCount();
    const std::vector<std::uint8_t> edgeOnSurface = detail::surfaceEdgeMask(topo);
    CollapsePlan plan;
    plan.target.resize(N);
    std::iota(plan.target.begin(), plan.target.end(), 0);
    std::vector<std::uint8_t> used(N, 0);
    for (const Index* pe = sheets.sheetEdges.begin(sheet); pe != sheets.sheetEdges.end(sheet); ++pe) {
        const auto [a, b] = topo.edges[*pe];
        const NodeClass ca = mesh.nodeClass[a], cb = mesh.nodeClass[b];
        const bool fa = ca.kind != NodeKind::Interior, fb = cb.kind != NodeKind::Interior;
        auto refuse = [&](const std::string& why) {
            throw Error("cannot collapse sheet " + std::to_string(sheet) + ": its edge from node " +
                        std::to_string(a) + " " + at(mesh.nodes[a]) + " to node " + std::to_string(b) + " " + why);
        };
        if (used[a] || used[b]) refuse("shares a node with another of its edges (the sheet touches itself)");
        used[a] = used[b] = 1;
        Index keep = a, gone = b;
        Vec3 pos = mesh.nodes[a];
        NodeClass cls = ca;
        if (fa && fb) {
            if (!(ca == cb)) refuse("joins two different surfaces or curves; collapsing it would merge them");
            if (ca.kind != NodeKind::Surface || !edgeOnSurface[*pe])
                refuse("runs through the solid between two nodes of one surface; collapsing it would pinch the surface");
            pos = 0.5 * (mesh.nodes[a] + mesh.nodes[b]);
        } else if (fb) {
            keep = b;
            gone = a;
            pos = mesh.nodes[b];
            cls = cb;
        } else if (!fa) {
            pos = 0.5 * (mesh.nodes[a] + mesh.nodes[b]);
        }
        plan.target[gone] = keep;
        plan.target[keep] = keep;
        plan.newPos.push_back(pos);
        plan.newClass.push_back(cls);
    }
    return plan;
}

// The mesh without the sheet's hexes: nodes that stay are renumbered in
// order (a merged pair takes its planned position and class), the other hexes
// keep their order with their corners remapped.
HexMesh collapsedMesh(const HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet,
                      const CollapsePlan& plan) {
    const std::size_t N = mesh.nodeCount();
    const std::vector<Index>& target = plan.target;
    HexMesh out;
    std::vector<std::uint8_t> inSheet(mesh.hexCount(), 0);
    for (const Index* h = sheets.sheetHexes.begin(sheet); h != sheets.sheetHexes.end(sheet); ++h) inSheet[*h] = 1;
    std::vector<Index> newId(N, kNone);
    Index nextNode = 0;
    for (std::size_t v = 0; v < N; ++v)
        if (target[v] == static_cast<Index>(v)) newId[v] = nextNode++;
    out.nodes.resize(nextNode);
    out.nodeClass.resize(nextNode);
    for (std::size_t v = 0; v < N; ++v)
        if (newId[v] != kNone) {
            out.nodes[newId[v]] = mesh.nodes[v];
            out.nodeClass[newId[v]] = mesh.nodeClass[v];
        }
    std::size_t i = 0;
    for (const Index* pe = sheets.sheetEdges.begin(sheet); pe != sheets.sheetEdges.end(sheet); ++pe, ++i) {
        const auto [a, b] = topo.edges[*pe];
        const Index keep = target[a] == a ? a : b;
        out.nodes[newId[keep]] = plan.newPos[i];
        out.nodeClass[newId[keep]] = plan.newClass[i];
    }
    for (std::size_t h = 0; h < mesh.hexCount(); ++h) {
        if (inSheet[h]) continue;
        Hex nh;
        for (int c = 0; c < 8; ++c) nh[c] = newId[target[mesh.hexes[h][c]]];
        out.addHex(nh, mesh.material[h]);
    }
    out.surfaces = mesh.surfaces;
    return out;
}

// Defect kinds of a validity report other than inverted hexes.
std::set<std::string> defectKinds(const ValidityReport& r) {
    std::set<std::string> out;
    for (const auto& [key, d] : r.defects)
        if (key != "inverted_hex") out.insert(key);
    return out;
}

// Hexes with the same eight nodes as another (validate()'s duplicate_hex
// count), by sorting the hexes' node sets: the refusal most random sheets of
// a pillowed mesh meet, found without a full validation.
std::size_t duplicateHexes(const HexMesh& mesh) {
    std::vector<Hex> keys(mesh.hexes.begin(), mesh.hexes.end());
    for (Hex& k : keys) std::sort(k.begin(), k.end());
    std::sort(keys.begin(), keys.end());
    return static_cast<std::size_t>(keys.end() - std::unique(keys.begin(), keys.end()));
}

// Throws if the collapse removed every hex of a material, or made a kind of
// topological defect the mesh did not have; else returns the defect kinds of
// `after` (topologicalDefects).
std::set<std::string> requireSound(const HexMesh& before, const std::set<std::string>& defectsBefore,
                                   const HexMesh& after, Index sheet) {
    const std::set<std::int32_t> was(before.material.begin(), before.material.end());
    const std::set<std::int32_t> is(after.material.begin(), after.material.end());
    for (std::int32_t m : was)
        if (!is.count(m))
            throw Error("cannot collapse sheet " + std::to_string(sheet) + ": it holds every hex of material " +
                        std::to_string(m));
    if (!defectsBefore.count("duplicate_hex"))
        if (const std::size_t d = duplicateHexes(after); d > 0)
            throw Error("cannot collapse sheet " + std::to_string(sheet) + ": the result would have " +
                        std::to_string(d) + " defect(s) of kind duplicate_hex");
    const ValidityReport rep = validate(after);
    std::set<std::string> kinds = defectKinds(rep);
    for (const auto& key : kinds)
        if (!defectsBefore.count(key))
            throw Error("cannot collapse sheet " + std::to_string(sheet) + ": the result would have " +
                        std::to_string(rep.count(key)) + " defect(s) of kind " + key);
    return kinds;
}

}  // namespace

std::set<std::string> topologicalDefects(const HexMesh& mesh) { return defectKinds(validate(mesh)); }

std::size_t collapse(HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet) {
    return collapse(mesh, topo, sheets, sheet, topologicalDefects(mesh));
}

std::size_t collapse(HexMesh& mesh, const Topology& topo, const DualSheets& sheets, Index sheet,
                     const std::set<std::string>& defectsBefore, std::set<std::string>* defectsAfter) {
    if (sheet < 0 || static_cast<std::size_t>(sheet) >= sheets.count())
        throw Error("collapse: no sheet " + std::to_string(sheet));
    const CollapsePlan plan = planEdgeCollapses(mesh, topo, sheets, sheet);
    HexMesh out = collapsedMesh(mesh, topo, sheets, sheet, plan);
    std::set<std::string> kinds = requireSound(mesh, defectsBefore, out, sheet);
    const std::size_t removed = mesh.hexCount() - out.hexCount();
    mesh = std::move(out);
    if (defectsAfter) *defectsAfter = std::move(kinds);
    return removed;
}

}  // namespace isohex

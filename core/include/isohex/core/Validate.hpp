#pragma once
// Checks of the seed's primal constraints (section 2.4.1) that can be decided
// from the mesh alone.
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/Topology.hpp"

namespace isohex {

// One kind of defect, with how many there are and a few examples so a user
// can find them (ids are 0-based; `where` is a world position).
struct DefectKind {
    std::string constraint;              // letter(s) of the seed's constraint, e.g. "I", "N"
    std::string description;             // one line for a person
    std::size_t count = 0;
    std::vector<Index> examples;         // up to kMaxExamples entity ids (hex, quad, edge or node)
    std::string entity;                  // "hex", "quad", "edge" or "node"
    std::vector<Vec3> where;             // positions of the examples
};

struct ValidityReport {
    // Keyed by a stable machine name (see validate()). Only kinds found are present.
    std::map<std::string, DefectKind> defects;
    bool ok() const { return defects.empty(); }
    std::size_t count(const std::string& key) const {
        auto it = defects.find(key);
        return it == defects.end() ? 0 : it->second.count;
    }
};

inline constexpr std::size_t kMaxExamples = 10;

// Defect keys, the entity each one counts, and the seed's constraint letter(s):
//   repeated_node        hex    a hex uses a node twice (B, D, G)
//   overfull_quad        quad   a quad in more than two hexes (H)
//   duplicate_hex        hex    same node set as a lower-numbered hex, so only
//                               the later copies are counted (I)
//   hex_doublet          hex    shares two or more quads with one other hex (I);
//                               both hexes of a doublet are counted
//   quad_doublet         quad   two surface quads share two or more edges (E)
//   nonmanifold_edge     edge   a surface edge with three or more quads of one
//                               surface, or with one quad of a surface and no
//                               other surface there to end it (K)
//   nonmanifold_node     node   the quads of one surface around the node form
//                               more than one fan: the pinch where two solids
//                               touch at a vertex or along an edge (K)
//   inconsistent_orientation  quad  both hexes on it traverse it in the same
//                               direction: one is folded onto the other (N)
//   inverted_hex         hex    a corner or the centre Jacobian determinant <= 0 (N)
//   unused_node          node   node in no hex (A)
//   coincident_node      node   a boundary node at the same place as another
//                               (within a millionth of the boundary's box):
//                               duplicated, unmerged nodes leave the hexes
//                               there disconnected (no letter: the seed's
//                               constraints take connectivity as given)
//
// "Surface" means a patch of surfacePatches(): boundary quads grouped by
// (material inside, exterior) and interface quads by their two materials. A
// surface may be open (an interface ends where it meets the exterior), so an
// edge with one quad of a surface is fine where another surface also has the
// edge, and a node's fan may be a path rather than a cycle.
//
// Each defect is reported once, under its root cause: hexes with a repeated
// node are not also judged for inversion or orientation, and two hexes with the
// same node set are not also reported as a doublet or as misoriented. Results
// that follow geometrically do appear: a hex doublet always has a corner of
// 180 degrees or more (inverted_hex), and where its two hexes reach the
// surface their faces there form quad doublets.
//
// Ids of quads and edges are those buildTopology(mesh) gives them.
//
// Cost: linear in the mesh size (plus small per-node sorts), parallel over
// hexes, nodes and surface quads; the report does not depend on the thread
// count. Memory: the node-to-hex rows and the surface quads
// (TopologyParts::Surfaces), about 45 bytes per hex on a brain.
ValidityReport validate(const HexMesh& mesh);

// The report's "validity" object: {"ok": bool, "defects": {key: {"constraint",
// "description", "count", "entity", "examples": [ids], "where": [[x, y, z]]}}}.
nlohmann::json toJson(const ValidityReport& r);

}  // namespace isohex

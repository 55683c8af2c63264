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

// Defect keys:
//   repeated_node        hex uses a node twice (B, D, G)
//   overfull_quad        quad in more than two hexes (H)
//   duplicate_hex        two hexes with the same node set
//   hex_doublet          two hexes share two or more quads (I)
//   quad_doublet         two boundary quads share two or more edges (E)
//   nonmanifold_edge     boundary edge without exactly two boundary quads of one surface (K)
//   nonmanifold_node     boundary quads around a node are not one fan (pinch, seed Fig. 7.13)
//   inconsistent_orientation  two hexes see their shared quad with the same orientation
//   inverted_hex         a corner Jacobian determinant <= 0 (N)
//   unused_node          node in no hex (A)
ValidityReport validate(const HexMesh& mesh);
ValidityReport validate(const HexMesh& mesh, const Topology& topo);

nlohmann::json toJson(const ValidityReport& r);

}  // namespace isohex

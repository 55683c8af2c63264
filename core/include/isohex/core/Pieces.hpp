#pragma once
// The separate pieces of a hex mesh: its hexes joined through shared nodes.
// A finite-element model needs every piece held in place (a piece with no
// support and no contact leaves the stiffness matrix singular), so the mesh
// report counts the pieces and says where the small ones are.
#include <cstddef>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "isohex/core/HexMesh.hpp"

namespace isohex {

struct MeshPiece {
    std::size_t hexes = 0;
    Vec3 at{0, 0, 0};  // the centroid of its lowest-numbered hex
};

// Every piece, the most hexes first (ties: the piece with the
// lowest-numbered hex first); none for a mesh without hexes. Linear in the
// hexes; the same for any thread count.
std::vector<MeshPiece> meshPieces(const HexMesh& mesh);

// For the report: "count", "largest_hexes", "other_hexes" and "others" (the
// next kMaxPiecesListed pieces, most hexes first, each with "hexes" and "at").
inline constexpr std::size_t kMaxPiecesListed = 10;
nlohmann::json toJson(const std::vector<MeshPiece>& pieces);

// "108 separate pieces: the largest has 1,911,500 hexes, the other 107 have
// 2,849 hexes together (the biggest of them 389 hexes, at (x, y, z))", or for
// two "... the other has 989 hexes, at (x, y, z)"; empty for one piece or none.
std::string describePieces(const std::vector<MeshPiece>& pieces);

}  // namespace isohex

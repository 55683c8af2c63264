#include "isohex/core/Pieces.hpp"

#include <algorithm>
#include <cstdint>
#include <sstream>

#include "isohex/core/DisjointSets.hpp"
#include "isohex/core/Quality.hpp"

namespace isohex {

std::vector<MeshPiece> meshPieces(const HexMesh& mesh) {
    DisjointSets<Index> nodes(mesh.nodeCount());
    for (const auto& hex : mesh.hexes)
        for (Index v : hex) nodes.unite(hex[0], v);
    // pieces numbered by their lowest-numbered hex, in hex order
    std::vector<std::int64_t> pieceOfRoot(mesh.nodeCount(), -1);
    std::vector<MeshPiece> pieces;
    for (std::size_t h = 0; h < mesh.hexCount(); ++h) {
        const auto root = static_cast<std::size_t>(nodes.find(mesh.hexes[h][0]));
        if (pieceOfRoot[root] < 0) {
            pieceOfRoot[root] = static_cast<std::int64_t>(pieces.size());
            pieces.push_back({0, hexCentre(mesh, static_cast<Index>(h))});
        }
        ++pieces[static_cast<std::size_t>(pieceOfRoot[root])].hexes;
    }
    std::stable_sort(pieces.begin(), pieces.end(), [](const MeshPiece& a, const MeshPiece& b) { return a.hexes > b.hexes; });
    return pieces;
}

nlohmann::json toJson(const std::vector<MeshPiece>& pieces) {
    nlohmann::json j = {{"count", pieces.size()}, {"largest_hexes", pieces.empty() ? 0 : pieces.front().hexes}};
    std::size_t others = 0;
    nlohmann::json listed = nlohmann::json::array();
    for (std::size_t i = 1; i < pieces.size(); ++i) {
        others += pieces[i].hexes;
        if (listed.size() < kMaxPiecesListed) listed.push_back({{"hexes", pieces[i].hexes}, {"at", pieces[i].at}});
    }
    j["other_hexes"] = others;
    j["others"] = listed;
    return j;
}

namespace {
// 1912000 -> "1,912,000"
std::string grouped(std::size_t n) {
    std::string s = std::to_string(n);
    for (int i = static_cast<int>(s.size()) - 3; i > 0; i -= 3) s.insert(static_cast<std::size_t>(i), ",");
    return s;
}
std::string hexes(std::size_t n) { return grouped(n) + (n == 1 ? " hex" : " hexes"); }
}  // namespace

std::string describePieces(const std::vector<MeshPiece>& pieces) {
    if (pieces.size() < 2) return {};
    std::size_t others = 0;
    for (std::size_t i = 1; i < pieces.size(); ++i) others += pieces[i].hexes;
    const MeshPiece& next = pieces[1];
    std::ostringstream where;
    where << "at (" << next.at[0] << ", " << next.at[1] << ", " << next.at[2] << ")";
    const std::string at = where.str();
    const std::string s = grouped(pieces.size()) + " separate pieces: the largest has " + hexes(pieces.front().hexes);
    if (pieces.size() == 2) return s + ", the other has " + hexes(next.hexes) + ", " + at;
    return s + ", the other " + grouped(pieces.size() - 1) + " have " + hexes(others) + " together (the biggest of them " +
           hexes(next.hexes) + ", " + at + ")";
}

}  // namespace isohex

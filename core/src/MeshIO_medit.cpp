// MEDIT / Gamma (.mesh), ASCII, double precision (MeshVersionFormatted 2).
//
// Vertices carry reference = surface id + 1 for nodes classified on a surface,
// else 0. Quadrilaterals are the boundary and interface quads, oriented out
// of the surface's `inside` material, with reference = surface position + 1.
// Hexahedra carry the material as reference. MEDIT numbers hexahedron corners
// like VTK_HEXAHEDRON (four corners of one face counter-clockwise seen from
// the inside, then the opposite face in the same order), so corners are
// written as stored, 1-based.
#include <string>

#include "MeshIODetail.hpp"

namespace isohex::io::detail {

void writeMedit(const HexMesh& mesh, const std::string& tmpPath, const std::string& path) {
    const std::vector<NamedPatch> surfaces = namedSurfaces(mesh);
    TextOut out(tmpPath, path);
    out << "MeshVersionFormatted 2\n\nDimension 3\n\n";

    out << "Vertices\n" << mesh.nodeCount() << '\n';
    for (std::size_t i = 0; i < mesh.nodeCount(); ++i) {
        const Vec3& p = mesh.nodes[i];
        const NodeClass& c = mesh.nodeClass[i];
        const std::int64_t ref = c.kind == NodeKind::Surface && c.id >= 0 ? std::int64_t{c.id} + 1 : 0;
        out << p[0] << ' ' << p[1] << ' ' << p[2] << ' ' << ref << '\n';
    }

    std::size_t quads = 0;
    for (const NamedPatch& s : surfaces) quads += s.patch.hexFaces.size();
    if (quads > 0) {
        out << "\nQuadrilaterals\n" << quads << '\n';
        for (std::size_t s = 0; s < surfaces.size(); ++s)
            for (const auto& [hex, face] : surfaces[s].patch.hexFaces) {
                for (Index v : faceNodes(mesh, hex, face)) out << static_cast<std::int64_t>(v + 1) << ' ';
                out << static_cast<std::int64_t>(s + 1) << '\n';
            }
    }

    if (mesh.hexCount() > 0) {
        out << "\nHexahedra\n" << mesh.hexCount() << '\n';
        for (std::size_t h = 0; h < mesh.hexCount(); ++h) {
            for (Index v : mesh.hexes[h]) out << static_cast<std::int64_t>(v + 1) << ' ';
            out << mesh.material[h] << '\n';
        }
    }
    out << "\nEnd\n";
    out.close();
}

}  // namespace isohex::io::detail

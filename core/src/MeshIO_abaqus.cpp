// Abaqus / CalculiX input (.inp), mesh part only: nodes, C3D8 elements in one
// ELSET per material (MAT_<id>), and per surface an element-based *SURFACE
// built from one ELSET per face number. The file is meant to be *INCLUDEd by
// an analysis deck that adds materials, sections, loads and steps; it carries
// the deck's *HEADING, so that deck must not have another (CalculiX stops on
// a second one).
//
// C3D8 corner order equals VTK_HEXAHEDRON's. Abaqus/CalculiX face numbers of a
// C3D8 (1-based corners): S1 = 1-2-3-4, S2 = 5-8-7-6, S3 = 1-5-6-2,
// S4 = 2-6-7-3, S5 = 3-7-8-4, S6 = 4-8-5-1.
#include <array>
#include <charconv>
#include <cstdio>
#include <string>

#include "MeshIODetail.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::io::detail {

namespace {

// Abaqus face number of our local face f (hexcell::kFaces): face 0 {0,4,7,3}
// is corners 1-5-8-4 = S6, face 1 {1,2,6,5} = 2-3-7-6 = S4, face 2 {0,1,5,4}
// = 1-2-6-5 = S3, face 3 {3,7,6,2} = 4-8-7-3 = S5, face 4 {0,3,2,1} = S1,
// face 5 {4,5,6,7} = S2.
constexpr std::array<int, 6> kAbaqusFace = {6, 4, 3, 5, 1, 2};

// Abaqus labels start with a letter and hold letters, digits and underscores
// (at most 80 characters); anything else becomes '_'.
std::string abaqusLabel(const std::string& name) {
    std::string s;
    for (char c : name) {
        const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
        s.push_back(ok ? c : '_');
    }
    if (s.empty() || !((s[0] >= 'a' && s[0] <= 'z') || (s[0] >= 'A' && s[0] <= 'Z'))) s = "S_" + s;
    if (s.size() > 72) s.resize(72);  // room for the "_S<n>" element-set suffix
    return s;
}

std::string materialLabel(std::int32_t m) {
    return m < 0 ? "MAT_N" + std::to_string(-static_cast<std::int64_t>(m)) : "MAT_" + std::to_string(m);
}

// Data lines are kept well under CalculiX's 132-character limit.
constexpr int kIdsPerLine = 8;

// CalculiX reads a number of at most 20 characters per field (a longer one
// stops it with "*ERROR reading *NODE"). The shortest text that reads back
// to the same double fits for most coordinates ("-39.523961133177562" is 19);
// near zero it is in exponent form and can be 22 ("-1.813617615035761e-05"),
// so those take 14 significant digits (13 with a three-digit exponent): a
// relative change below 1e-13.
std::string abaqusNumber(double v) {
    char buf[32];
    const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
    if (ec == std::errc() && end - buf <= 20) return std::string(buf, end);
    for (int digits = 13; digits >= 10; --digits) {
        const int n = std::snprintf(buf, sizeof buf, "%.*e", digits, v);
        if (n > 0 && n <= 20) return std::string(buf, static_cast<std::size_t>(n));
    }
    return std::string(buf);  // not reached for finite doubles
}

}  // namespace

void writeAbaqus(const HexMesh& mesh, const std::string& tmpPath, const std::string& path) {
    TextOut out(tmpPath, path);
    out << "*HEADING\nisohex hexahedral mesh: " << mesh.nodeCount() << " nodes, " << mesh.hexCount()
        << " C3D8 elements\n";
    out << "** Units are those of the mesh (millimetres for scans). Materials: ELSET MAT_<id>.\n";

    out << "*NODE\n";
    for (std::size_t i = 0; i < mesh.nodeCount(); ++i) {
        const Vec3& p = mesh.nodes[i];
        out << static_cast<std::int64_t>(i + 1) << ", " << abaqusNumber(p[0]) << ", " << abaqusNumber(p[1]) << ", "
            << abaqusNumber(p[2]) << '\n';
    }

    const std::vector<std::int32_t> mats = materialsOf(mesh);
    const auto byMaterial = hexesByMaterial(mesh, mats);
    for (std::size_t i = 0; i < mats.size(); ++i) {
        out << "*ELEMENT, TYPE=C3D8, ELSET=" << materialLabel(mats[i]) << '\n';
        for (Index h : byMaterial[i]) {
            out << static_cast<std::int64_t>(h) + 1;
            for (Index v : mesh.hexes[h]) out << ", " << static_cast<std::int64_t>(v + 1);
            out << '\n';
        }
    }

    for (const NamedPatch& s : namedSurfaces(mesh)) {
        const std::string label = abaqusLabel(s.name);
        std::array<std::vector<Index>, 7> byFace;  // index = Abaqus face number
        for (const auto& [hex, face] : s.patch.hexFaces) byFace[kAbaqusFace[face]].push_back(hex);
        out << "** surface " << s.name << " (material " << s.patch.tag.inside << " against "
            << (s.patch.tag.outside < 0 ? std::string("the exterior")
                                        : "material " + std::to_string(s.patch.tag.outside))
            << "), faces oriented out of material " << s.patch.tag.inside << '\n';
        for (int f = 1; f <= 6; ++f) {
            if (byFace[f].empty()) continue;
            out << "*ELSET, ELSET=" << label << "_S" << static_cast<std::int64_t>(f) << '\n';
            for (std::size_t i = 0; i < byFace[f].size(); ++i) {
                out << static_cast<std::int64_t>(byFace[f][i] + 1);
                const bool endOfLine = (i + 1) % kIdsPerLine == 0 || i + 1 == byFace[f].size();
                out << (endOfLine ? "\n" : ", ");
            }
        }
        out << "*SURFACE, TYPE=ELEMENT, NAME=" << label << '\n';
        for (int f = 1; f <= 6; ++f)
            if (!byFace[f].empty())
                out << label << "_S" << static_cast<std::int64_t>(f) << ", S" << static_cast<std::int64_t>(f) << '\n';
    }
    out.close();
}

}  // namespace isohex::io::detail

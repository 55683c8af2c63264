// Gmsh MSH 4.1 (.msh) through the Gmsh C++ API.
//
// Layout written: one discrete volume per material (entity tag = position in
// the ascending material list + 1) holding its hexes (type 5, tag = hex index
// + 1), with a physical group named "material_<id>"; one discrete surface per
// boundary/interface surface holding its quads (type 3, oriented out of the
// `inside` material) with a physical group named after the surface. All nodes
// (tag = node index + 1) sit on the first volume so the file lists them in
// index order, which keeps numbering identical for readers that renumber by
// file position.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <numeric>
#include <sstream>
#include <string>
#include <system_error>
#include <unordered_map>

#include <gmsh.h>

#include "MeshIODetail.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::io::detail {

namespace {

constexpr int kGmshHex8 = 5;
constexpr int kGmshQuad4 = 3;

// Gmsh keeps one global model and must be initialised / finalised around
// use; this guard does both and serialises callers (the API is not re-entrant).
class GmshSession {
public:
    explicit GmshSession(const std::string& path) : lock_(mutex()), path_(path) {
        try {
            gmsh::initialize(0, nullptr, false);
            gmsh::option::setNumber("General.Terminal", 0);
            gmsh::option::setNumber("General.Verbosity", 0);
        } catch (...) {
            fail("could not start Gmsh");
        }
    }
    ~GmshSession() {
        try {
            gmsh::finalize();
        } catch (...) {
        }
    }
    GmshSession(const GmshSession&) = delete;
    GmshSession& operator=(const GmshSession&) = delete;

    // Rethrows the exception being handled as an isohex::Error naming the file.
    [[noreturn]] void fail(const std::string& doing) const {
        std::string why;
        try {
            throw;
        } catch (const Error&) {
            throw;
        } catch (const std::string& s) {
            why = s;
        } catch (const std::exception& e) {
            why = e.what();
        } catch (...) {
        }
        if (why.empty()) {
            try {
                gmsh::logger::getLastError(why);
            } catch (...) {
            }
        }
        for (char& c : why)
            if (c == '\n' || c == '\r') c = ' ';
        throw Error(path_ + ": " + doing + (why.empty() ? std::string() : ": " + why));
    }

private:
    static std::mutex& mutex() {
        static std::mutex m;
        return m;
    }
    std::lock_guard<std::mutex> lock_;
    std::string path_;
};

std::string materialGroupName(std::int32_t material) { return "material_" + std::to_string(material); }

// "material_<n>" -> n, as written above; anything else -> false.
bool parseMaterialName(const std::string& name, std::int32_t& out) {
    const std::string prefix = "material_";
    if (name.rfind(prefix, 0) != 0) return false;
    const char* b = name.data() + prefix.size();
    const char* e = name.data() + name.size();
    auto r = std::from_chars(b, e, out);
    return r.ec == std::errc() && r.ptr == e && b != e;
}


// Gmsh's writer does not check its writes: on a full disk it leaves a
// truncated file and reports success. Its file ends with the $Elements
// section, so a file that does not end with its closing tag is incomplete.
void requireCompleteMsh(const std::string& tmpPath, const std::string& path) {
    const std::string tag = "$EndElements\n";
    std::ifstream in(tmpPath, std::ios::binary | std::ios::ate);
    const std::streamoff size = in ? static_cast<std::streamoff>(in.tellg()) : 0;
    std::string tail(tag.size(), '\0');
    if (size >= static_cast<std::streamoff>(tag.size())) {
        in.seekg(size - static_cast<std::streamoff>(tag.size()));
        in.read(tail.data(), static_cast<std::streamsize>(tag.size()));
    }
    if (!in || tail != tag)
        throw Error(path + ": could not write the Gmsh file: Gmsh stopped before its end ($EndElements); check that the folder "
                    "has room and can be written, and try again");
}

}  // namespace

void writeMsh(const HexMesh& mesh, const std::string& tmpPath, const std::string& path) {
    const std::vector<std::int32_t> mats = materialsOf(mesh);
    const std::vector<int> physTags = positiveIds(mats);
    const std::vector<NamedPatch> surfaces = namedSurfaces(mesh);

    GmshSession gmshSession(path);
    try {
        gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
        gmsh::option::setNumber("Mesh.Binary", 0);
        gmsh::option::setNumber("Mesh.SaveAll", 0);
        gmsh::model::add("isohex");

        const int nodeEntity = 1;  // io::write refuses meshes without hexes, so it exists
        for (std::size_t i = 0; i < mats.size(); ++i) gmsh::model::addDiscreteEntity(3, static_cast<int>(i + 1));

        std::vector<std::size_t> nodeTags(mesh.nodeCount());
        std::iota(nodeTags.begin(), nodeTags.end(), std::size_t{1});
        std::vector<double> coords(3 * mesh.nodeCount());
        for (std::size_t i = 0; i < mesh.nodeCount(); ++i)
            for (int k = 0; k < 3; ++k) coords[3 * i + k] = mesh.nodes[i][k];
        gmsh::model::mesh::addNodes(3, nodeEntity, nodeTags, coords);
        nodeTags = {};
        coords = {};

        const auto byMaterial = hexesByMaterial(mesh, mats);
        for (std::size_t i = 0; i < mats.size(); ++i) {
            std::vector<std::size_t> elemTags, conn;
            elemTags.reserve(byMaterial[i].size());
            conn.reserve(8 * byMaterial[i].size());
            for (Index h : byMaterial[i]) {
                elemTags.push_back(static_cast<std::size_t>(h) + 1);
                for (Index v : mesh.hexes[h]) conn.push_back(static_cast<std::size_t>(v) + 1);
            }
            const int entity = static_cast<int>(i + 1);
            gmsh::model::mesh::addElementsByType(entity, kGmshHex8, elemTags, conn);
            gmsh::model::addPhysicalGroup(3, {entity}, physTags[i]);
            gmsh::model::setPhysicalName(3, physTags[i], materialGroupName(mats[i]));
        }

        std::size_t nextElement = mesh.hexCount() + 1;
        for (std::size_t s = 0; s < surfaces.size(); ++s) {
            const int entity = static_cast<int>(s + 1);
            gmsh::model::addDiscreteEntity(2, entity);
            std::vector<std::size_t> elemTags, conn;
            for (const auto& [hex, face] : surfaces[s].patch.hexFaces) {
                elemTags.push_back(nextElement++);
                for (Index v : faceNodes(mesh, hex, face)) conn.push_back(static_cast<std::size_t>(v) + 1);
            }
            gmsh::model::mesh::addElementsByType(entity, kGmshQuad4, elemTags, conn);
            gmsh::model::addPhysicalGroup(2, {entity}, entity);
            gmsh::model::setPhysicalName(2, entity, surfaces[s].name);
        }
        gmsh::write(tmpPath);
        requireCompleteMsh(tmpPath, path);
    } catch (...) {
        gmshSession.fail("could not write the Gmsh file");
    }
}

namespace {

// Gmsh falls back to its script parser for a file that does not start with
// $MeshFormat, and reads a missing or binary-garbage file as an empty model;
// refuse those before Gmsh sees them.
void requireMshHeader(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::string line;
    while (std::getline(in, line)) {
        while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.pop_back();
        if (line.empty()) continue;
        if (line == "$MeshFormat") return;
        break;
    }
    throw Error(path + ": not a Gmsh mesh file (it does not start with $MeshFormat)");
}

// Gmsh 4.8's reader trusts the counts in an ASCII file's section headers:
// an $Elements header promising fewer elements than its blocks hold made it
// crash (segmentation fault in quality, convert and smooth, the latter two
// leaving a partial output; found by a helper's corrupted-input survey). So
// the $Nodes and $Elements sections of an ASCII file (format 4.1 or 2.2) are
// walked first: every block's lines present, the blocks adding up to the
// totals, the section closed where the counts say. Binary files are left to
// Gmsh (isohex writes ASCII).
void checkMshCounts(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::error_code ec;
    auto fileSize = static_cast<long long>(std::filesystem::file_size(path, ec));
    if (ec) fileSize = std::numeric_limits<long long>::max();
    std::string line;
    std::size_t lineNo = 0;
    auto next = [&]() -> bool {
        if (!std::getline(in, line)) return false;
        ++lineNo;
        while (!line.empty() && std::isspace(static_cast<unsigned char>(line.back()))) line.pop_back();
        return true;
    };
    auto fail = [&](const std::string& what) {
        throw Error(path + ": line " + std::to_string(lineNo) + ": " + what +
                    "; the file is damaged or truncated (re-export it)");
    };
    double version = 0;
    int fileType = 0;
    while (next()) {
        if (line == "$MeshFormat") {
            if (!next()) fail("the file ends in $MeshFormat");
            std::istringstream f(line);
            f >> version >> fileType;
            if (fileType != 0) return;  // binary: Gmsh's reader checks it
            // 4.1 and 2.x have the layouts walked below; 3.x and 4.0 are left to Gmsh
            if (!(version >= 4.1) && !(version >= 2 && version < 3)) return;
            continue;
        }
        const bool nodes = line == "$Nodes", elements = line == "$Elements";
        if (!nodes && !elements) continue;
        const std::string end = nodes ? "$EndNodes" : "$EndElements";
        const std::string what = nodes ? "node" : "element";
        if (!next()) fail("the file ends after " + std::string(nodes ? "$Nodes" : "$Elements"));
        std::istringstream head(line);
        if (version >= 4) {
            long long blocks = -1, total = -1, minTag = 0, maxTag = 0;
            if (!(head >> blocks >> total >> minTag >> maxTag) || blocks < 0 || total < 0)
                fail("the " + what + " section header is not 'blocks count minTag maxTag'");
            // a line per item at least: more than the file's bytes is a damaged count
            if (blocks > fileSize || total > fileSize) fail("the " + what + " section header's counts exceed the file");
            long long seen = 0;
            for (long long b = 0; b < blocks; ++b) {
                if (!next()) fail("the file ends in the " + what + " section");
                std::istringstream bh(line);
                long long dim = 0, tag = 0, kind = 0, count = -1;
                if (!(bh >> dim >> tag >> kind >> count) || count < 0 || count > fileSize)
                    fail("expected the header of " + what + " block " + std::to_string(b + 1) + " of " +
                         std::to_string(blocks));
                seen += count;
                if (seen > total)
                    fail("the " + what + " blocks hold more than the " + std::to_string(total) + " " + what +
                         "s the section header promises");
                // nodes: the tags, then the coordinates; elements: one line each
                const long long lines = nodes ? 2 * count : count;
                for (long long k = 0; k < lines; ++k) {
                    if (!next() || (!line.empty() && line[0] == '$'))
                        fail(what + " block " + std::to_string(b + 1) + " ends before its " + std::to_string(count) +
                             " " + what + "s");
                    if (!nodes || k < count) {  // a tag first on the line
                        std::istringstream t(line);
                        long long id = 0;
                        if (!(t >> id) || id < minTag || id > maxTag)
                            fail(what + " tag outside the range " + std::to_string(minTag) + " to " +
                                 std::to_string(maxTag) + " of the section header");
                    }
                }
            }
            if (seen != total)
                fail("the " + what + " blocks hold " + std::to_string(seen) + " " + what + "s but the section header promises " +
                     std::to_string(total));
        } else {
            long long total = -1;
            if (!(head >> total) || total < 0 || total > fileSize)
                fail("the " + what + " section does not start with its count");
            for (long long k = 0; k < total; ++k)
                if (!next() || (!line.empty() && line[0] == '$'))
                    fail("the " + what + " section ends before its " + std::to_string(total) + " " + what + "s");
        }
        if (!next() || line != end) fail("expected " + end + " after the " + what + "s the header counts");
    }
}

}  // namespace

HexMesh readMsh(const std::string& path) {
    requireMshHeader(path);
    checkMshCounts(path);
    HexMesh mesh;
    GmshSession gmshSession(path);
    try {
        gmsh::open(path);
    } catch (...) {
        gmshSession.fail("damaged or truncated Gmsh file");
    }
    try {
        std::vector<std::size_t> nodeTags;
        std::vector<double> coords, param;
        gmsh::model::mesh::getNodes(nodeTags, coords, param, -1, -1, false, false);
        if (nodeTags.empty()) throw Error(path + ": the Gmsh file holds no nodes (empty, damaged or truncated)");
        if (coords.size() != 3 * nodeTags.size()) throw Error(path + ": Gmsh returned inconsistent node data");
        if (nodeTags.size() > 2147483647u) throw Error(path + ": too many nodes for 32-bit indices");

        // Node index = rank of its tag, so tags 1..N (as isohex writes them) map to 0..N-1.
        std::vector<std::size_t> order(nodeTags.size());
        std::iota(order.begin(), order.end(), std::size_t{0});
        std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return nodeTags[a] < nodeTags[b]; });
        std::unordered_map<std::size_t, Index> indexOfTag;
        const bool dense = nodeTags[order.back()] == nodeTags.size() && nodeTags[order.front()] == 1;
        if (!dense) indexOfTag.reserve(nodeTags.size());
        mesh.nodes.resize(nodeTags.size());
        mesh.nodeClass.resize(nodeTags.size());
        for (std::size_t r = 0; r < order.size(); ++r) {
            const std::size_t i = order[r];
            if (r > 0 && nodeTags[order[r - 1]] == nodeTags[i])
                throw Error(path + ": node tag " + std::to_string(nodeTags[i]) + " appears twice");
            mesh.nodes[r] = {coords[3 * i], coords[3 * i + 1], coords[3 * i + 2]};
            if (!dense) indexOfTag.emplace(nodeTags[i], static_cast<Index>(r));
        }
        auto nodeIndex = [&](std::size_t tag) -> Index {
            if (dense) {
                if (tag >= 1 && tag <= nodeTags.size()) return static_cast<Index>(tag - 1);
            } else if (auto it = indexOfTag.find(tag); it != indexOfTag.end()) {
                return it->second;
            }
            throw Error(path + ": an element refers to node " + std::to_string(tag) + ", which the file does not define");
        };

        struct Element {
            std::size_t tag;
            Hex hex;
            std::int32_t material;
        };
        std::vector<Element> elements;
        gmsh::vectorpair volumes;
        gmsh::model::getEntities(volumes, 3);
        for (const auto& [dim, entity] : volumes) {
            std::vector<int> types;
            std::vector<std::vector<std::size_t>> elemTags, conn;
            gmsh::model::mesh::getElements(types, elemTags, conn, dim, entity);
            for (std::size_t t = 0; t < types.size(); ++t) {
                if (types[t] == kGmshHex8 || elemTags[t].empty()) continue;
                std::string name;
                int d, order, nn, npv;
                std::vector<double> lc;
                gmsh::model::mesh::getElementProperties(types[t], name, d, order, nn, lc, npv);
                throw Error(path + ": volume " + std::to_string(entity) + " holds " + std::to_string(elemTags[t].size()) +
                            " elements of type " + std::to_string(types[t]) + " (" + name +
                            "); isohex reads only 8-node hexahedra (type 5)");
            }
            std::vector<int> groups;
            gmsh::model::getPhysicalGroupsForEntity(dim, entity, groups);
            std::int32_t material = entity;
            if (!groups.empty()) {
                std::string name;
                gmsh::model::getPhysicalName(dim, groups.front(), name);
                if (!parseMaterialName(name, material)) material = groups.front();
            }
            for (std::size_t t = 0; t < types.size(); ++t) {
                if (types[t] != kGmshHex8) continue;
                if (conn[t].size() != 8 * elemTags[t].size())
                    throw Error(path + ": Gmsh returned inconsistent hexahedron data");
                for (std::size_t e = 0; e < elemTags[t].size(); ++e) {
                    Element el{elemTags[t][e], {}, material};
                    for (int k = 0; k < 8; ++k) el.hex[k] = nodeIndex(conn[t][8 * e + k]);
                    elements.push_back(el);
                }
            }
        }
        if (elements.empty())
            throw Error(path + ": the Gmsh file holds no 8-node hexahedra (element type 5) in any volume");
        if (elements.size() > 2147483647u) throw Error(path + ": too many hexahedra for 32-bit indices");
        // Element tags give the order, so hex i written as tag i+1 comes back as hex i.
        std::stable_sort(elements.begin(), elements.end(),
                         [](const Element& a, const Element& b) { return a.tag < b.tag; });
        mesh.hexes.reserve(elements.size());
        mesh.material.reserve(elements.size());
        for (const Element& e : elements) mesh.addHex(e.hex, e.material);
    } catch (const Error&) {
        throw;
    } catch (...) {
        gmshSession.fail("could not read the Gmsh file");
    }
    return mesh;
}

}  // namespace isohex::io::detail

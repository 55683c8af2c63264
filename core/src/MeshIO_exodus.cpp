// Exodus II (.exo, .e, .ex2) through libexodusII.
//
// One HEX8 element block per material (block id = material id when positive,
// else the next unused positive id; the block name "material_<id>" always
// carries the true id). Elements are numbered block by block; the element id
// map holds each element's isohex hex index + 1. Per boundary / interface
// surface: a side set (element, side) seen from the `inside` material and a
// node set, both with id = surface position + 1 and the surface's name.
// HEX8 corner order is VTK's; local faces map to Exodus sides by
// hexcell::kExodusSide.
#include <algorithm>
#include <mutex>
#include <string>
#include <vector>

#include <exodusII.h>

#include "MeshIODetail.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/HexCell.hpp"

namespace isohex::io::detail {

namespace {

// libexodusII keeps its options and last error in process-wide state.
std::mutex& exodusMutex() {
    static std::mutex m;
    return m;
}

class ExodusFile {
public:
    ExodusFile(const std::string& tmpPath, const std::string& path) : path_(path) {
        int cpuWordSize = sizeof(double), ioWordSize = sizeof(double);
        id_ = ex_create(tmpPath.c_str(), EX_CLOBBER, &cpuWordSize, &ioWordSize);
        if (id_ < 0) fail("ex_create", id_);
    }
    ~ExodusFile() {
        if (id_ >= 0) ex_close(id_);
    }
    ExodusFile(const ExodusFile&) = delete;
    ExodusFile& operator=(const ExodusFile&) = delete;

    int id() const { return id_; }

    // Every ex_* call goes through here: a negative status is an error
    // (positive ones are warnings, which libexodusII also reports).
    void check(int status, const char* call) const {
        if (status < 0) fail(call, status);
    }

    void close() {
        const int id = id_;
        id_ = -1;
        check(ex_close(id), "ex_close");
    }

private:
    [[noreturn]] void fail(const char* call, int status) const {
        const char *msg = nullptr, *func = nullptr;
        int code = 0;
        ex_get_err(&msg, &func, &code);
        std::string why = (msg && *msg) ? msg : "status " + std::to_string(status);
        for (char& c : why)
            if (c == '\n') c = ' ';
        throw Error(path_ + ": could not write the Exodus II file (" + call + " failed: " + why + ")");
    }

    std::string path_;
    int id_ = -1;
};

// Exodus names hold at most MAX_NAME_LENGTH (32) characters.
std::string exodusName(const std::string& name) {
    return name.size() <= static_cast<std::size_t>(MAX_NAME_LENGTH) ? name : name.substr(0, MAX_NAME_LENGTH);
}

// ex_put_names wants char*[]; keep the strings alive beside the pointers.
struct NameList {
    std::vector<std::string> names;
    std::vector<char*> pointers() {
        std::vector<char*> p;
        for (auto& n : names) p.push_back(n.data());
        return p;
    }
};

}  // namespace

void writeExodus(const HexMesh& mesh, const std::string& tmpPath, const std::string& path) {
    const std::vector<std::int32_t> mats = materialsOf(mesh);
    const std::vector<NamedPatch> surfaces = namedSurfaces(mesh);
    const auto nNodes = static_cast<int>(mesh.nodeCount());
    const auto nHexes = static_cast<int>(mesh.hexCount());

    const std::vector<int> blockIds = positiveIds(mats);

    // Exodus numbers elements 1..n in block order.
    std::vector<int> exodusElement(mesh.hexCount());
    std::vector<int> idMap;
    idMap.reserve(mesh.hexCount());
    std::vector<std::vector<int>> blockConn(mats.size());
    const auto byMaterial = hexesByMaterial(mesh, mats);
    for (std::size_t b = 0; b < mats.size(); ++b) {
        blockConn[b].reserve(8 * byMaterial[b].size());
        for (Index h : byMaterial[b]) {
            idMap.push_back(h + 1);
            exodusElement[h] = static_cast<int>(idMap.size());
            for (Index v : mesh.hexes[h]) blockConn[b].push_back(v + 1);
        }
    }

    std::lock_guard<std::mutex> lock(exodusMutex());
    ex_opts(EX_DEFAULT);  // report errors through return codes only, never print or abort
    ExodusFile exo(tmpPath, path);
    const int id = exo.id();

    exo.check(ex_put_init(id, "isohex hexahedral mesh", 3, nNodes, nHexes, static_cast<int>(mats.size()),
                          static_cast<int>(surfaces.size()), static_cast<int>(surfaces.size())),
              "ex_put_init");

    {
        std::vector<double> x(nNodes), y(nNodes), z(nNodes);
        for (int i = 0; i < nNodes; ++i) {
            x[i] = mesh.nodes[i][0];
            y[i] = mesh.nodes[i][1];
            z[i] = mesh.nodes[i][2];
        }
        exo.check(ex_put_coord(id, x.data(), y.data(), z.data()), "ex_put_coord");
        NameList axes{{"x", "y", "z"}};
        auto p = axes.pointers();
        exo.check(ex_put_coord_names(id, p.data()), "ex_put_coord_names");
    }

    NameList blockNames;
    for (std::size_t b = 0; b < mats.size(); ++b) {
        const auto count = static_cast<int>(blockConn[b].size() / 8);
        exo.check(ex_put_block(id, EX_ELEM_BLOCK, blockIds[b], "HEX8", count, 8, 0, 0, 0), "ex_put_block");
        exo.check(ex_put_conn(id, EX_ELEM_BLOCK, blockIds[b], blockConn[b].data(), nullptr, nullptr), "ex_put_conn");
        blockNames.names.push_back(exodusName("material_" + std::to_string(mats[b])));
    }
    if (!mats.empty()) {
        auto p = blockNames.pointers();
        exo.check(ex_put_names(id, EX_ELEM_BLOCK, p.data()), "ex_put_names (element blocks)");
        exo.check(ex_put_id_map(id, EX_ELEM_MAP, idMap.data()), "ex_put_id_map");
    }

    NameList setNames;
    for (std::size_t s = 0; s < surfaces.size(); ++s) {
        const int setId = static_cast<int>(s) + 1;
        const auto& faces = surfaces[s].patch.hexFaces;
        std::vector<int> elems, sides, nodes;
        elems.reserve(faces.size());
        sides.reserve(faces.size());
        for (const auto& [hex, face] : faces) {
            elems.push_back(exodusElement[hex]);
            sides.push_back(hexcell::kExodusSide[face]);
            for (Index v : faceNodes(mesh, hex, face)) nodes.push_back(v + 1);
        }
        std::sort(nodes.begin(), nodes.end());
        nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());

        exo.check(ex_put_set_param(id, EX_SIDE_SET, setId, static_cast<int>(elems.size()), 0), "ex_put_set_param (side set)");
        exo.check(ex_put_set(id, EX_SIDE_SET, setId, elems.data(), sides.data()), "ex_put_set (side set)");
        exo.check(ex_put_set_param(id, EX_NODE_SET, setId, static_cast<int>(nodes.size()), 0), "ex_put_set_param (node set)");
        exo.check(ex_put_set(id, EX_NODE_SET, setId, nodes.data(), nullptr), "ex_put_set (node set)");
        setNames.names.push_back(exodusName(surfaces[s].name));
    }
    if (!surfaces.empty()) {
        auto p = setNames.pointers();
        exo.check(ex_put_names(id, EX_SIDE_SET, p.data()), "ex_put_names (side sets)");
        exo.check(ex_put_names(id, EX_NODE_SET, p.data()), "ex_put_names (node sets)");
    }
    exo.close();
}

}  // namespace isohex::io::detail

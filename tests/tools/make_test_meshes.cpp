// Test helper for tests/py/test_io_roundtrip.py.
//
//   make_test_meshes OUTDIR [NX NY NZ H]
//       writes a two-material block (hexes renumbered by cube rotations so
//       every local face meets every side) as OUTDIR/block.{vtu,msh,exo,inp,mesh}
//       and the exact mesh as OUTDIR/block.truth.json
//   make_test_meshes --read FILE [OUT]
//       reads FILE with isohex::io::read, prints "nodes N hexes M materials ..."
//       or the error (exit 1); with OUT, writes what it read to OUT
#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "isohex/core/Error.hpp"
#include "isohex/core/MeshIO.hpp"
#include "tools/io_test_meshes.hpp"

using namespace isohex;

namespace {

int readMode(const std::string& path, const std::string& out) {
    try {
        const HexMesh m = io::read(path);
        std::cout << "nodes " << m.nodeCount() << " hexes " << m.hexCount() << " materials";
        std::vector<std::int32_t> mats(m.material);
        std::sort(mats.begin(), mats.end());
        mats.erase(std::unique(mats.begin(), mats.end()), mats.end());
        for (auto mat : mats) std::cout << ' ' << mat;
        std::cout << '\n';
        if (!out.empty()) { io::WriteOptions w; w.overwrite = true; io::write(m, out, w); }
        return 0;
    } catch (const Error& e) {
        std::cout << "error: " << e.what() << '\n';
        return 1;
    }
}

}  // namespace

int main(int argc, char** argv) {
    if (argc >= 3 && std::string(argv[1]) == "--read") return readMode(argv[2], argc >= 4 ? argv[3] : "");
    if (argc != 2 && argc != 6) {
        std::cerr << "usage: make_test_meshes OUTDIR [NX NY NZ H] | --read FILE [OUT]\n";
        return 2;
    }
    const std::string dir = argv[1];
    int nx = 4, ny = 3, nz = 2;
    double h = 0.5;
    if (argc == 6) {
        nx = std::atoi(argv[2]);
        ny = std::atoi(argv[3]);
        nz = std::atoi(argv[4]);
        h = std::atof(argv[5]);
    }
    try {
        const HexMesh mesh = iotest::makeTwoMaterialBlock(nx, ny, nz, h);
        io::WriteOptions opt;
        opt.overwrite = true;
        for (const char* ext : {".vtu", ".msh", ".exo", ".inp", ".mesh"}) io::write(mesh, dir + "/block" + ext, opt);

        nlohmann::json truth;
        truth["size"] = {nx, ny, nz};
        truth["h"] = h;
        truth["nodes"] = mesh.nodes;
        truth["hexes"] = mesh.hexes;
        truth["material"] = mesh.material;
        nlohmann::json kinds = nlohmann::json::array(), ids = nlohmann::json::array();
        for (const NodeClass& c : mesh.nodeClass) {
            kinds.push_back(static_cast<int>(c.kind));
            ids.push_back(c.id);
        }
        truth["node_class"] = kinds;
        truth["node_surface"] = ids;
        std::ofstream(dir + "/block.truth.json") << truth.dump() << '\n';
    } catch (const Error& e) {
        std::cerr << "make_test_meshes: " << e.what() << '\n';
        return 1;
    }
    return 0;
}

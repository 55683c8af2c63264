// Plugin libisohex_msh.so: Gmsh .msh files through the Gmsh library (MeshIO_msh.cpp).
#include "MeshFormatPlugin.hpp"
#include "MeshIODetail.hpp"

namespace {

using namespace isohex;

void write(const HexMesh& mesh, const std::string& tmpPath, const std::string& path, const io::WriteOptions&) {
    io::detail::writeMsh(mesh, tmpPath, path);
}

const io::detail::MeshFormatPlugin kApi{io::detail::MeshFormatPlugin::kAbi, write, io::detail::readMsh};

}  // namespace

extern "C" const void* isohex_plugin_api() { return &kApi; }

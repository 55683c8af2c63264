// Plugin libisohex_msh.so: Gmsh .msh files through the Gmsh library (MeshIO_msh.cpp).
#include "MeshFormatPlugin.hpp"
#include "MeshIODetail.hpp"

namespace {

using namespace isohex;

void write(const HexMesh& mesh, const std::string& tmpPath, const std::string& path, const io::WriteOptions&) {
    io::detail::writeMsh(mesh, tmpPath, path);
}

HexMesh read(const std::string& path, const io::detail::ArrayRequest*) { return io::detail::readMsh(path); }

const io::detail::MeshFormatPlugin kApi{io::detail::MeshFormatPlugin::kAbi, write, read};

}  // namespace

extern "C" const void* isohex_plugin_api() { return &kApi; }

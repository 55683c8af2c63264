// Plugin libisohex_exodus.so: Exodus II files through libexodusII (MeshIO_exodus.cpp).
#include "MeshFormatPlugin.hpp"
#include "MeshIODetail.hpp"

namespace {

using namespace isohex;

void write(const HexMesh& mesh, const std::string& tmpPath, const std::string& path, const io::WriteOptions&) {
    io::detail::writeExodus(mesh, tmpPath, path);
}

const io::detail::MeshFormatPlugin kApi{io::detail::MeshFormatPlugin::kAbi, write, nullptr};

}  // namespace

extern "C" const void* isohex_plugin_api() { return &kApi; }

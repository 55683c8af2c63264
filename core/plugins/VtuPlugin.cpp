// Plugin libisohex_vtu.so: .vtu files through VTK (MeshIO_vtu.cpp).
#include "MeshFormatPlugin.hpp"
#include "MeshIODetail.hpp"
#include "isohex/core/Quality.hpp"

namespace {

using namespace isohex;

void write(const HexMesh& mesh, const std::string& tmpPath, const std::string& path, const io::WriteOptions& opt) {
    if (opt.scaledJacobian.empty())
        io::detail::writeVtu(mesh, tmpPath, path, scaledJacobians(mesh), opt);
    else
        io::detail::writeVtu(mesh, tmpPath, path, opt.scaledJacobian, opt);
}

const io::detail::MeshFormatPlugin kApi{io::detail::MeshFormatPlugin::kAbi, write, io::detail::readVtu};

}  // namespace

extern "C" const void* isohex_plugin_api() { return &kApi; }

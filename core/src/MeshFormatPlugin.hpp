#pragma once
// Private to core: the mesh formats whose library is loaded on first use
// (isohex/core/Plugin.hpp). io::write and io::read call them through this
// table; core/plugins/<Format>Plugin.cpp fills it from MeshIO_<format>.cpp.
#include <string>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/MeshIO.hpp"
#include "MeshIODetail.hpp"

namespace isohex::io::detail {

struct MeshFormatPlugin {
    static constexpr int kAbi = 2;
    int abi;
    // Fills `tmpPath`; errors name `path`, the user's file.
    void (*write)(const HexMesh& mesh, const std::string& tmpPath, const std::string& path, const WriteOptions& opt);
    // nullptr for a format isohex only writes; `arrays` (readWithArrays) only for .vtu.
    HexMesh (*read)(const std::string& path, const ArrayRequest* arrays);
};

// The plugin of a format with a library (.vtu, .msh, Exodus), loaded on the
// first call; throws Error (Plugin.hpp) when it cannot be loaded.
const MeshFormatPlugin& meshFormatPlugin(Format format);

}  // namespace isohex::io::detail

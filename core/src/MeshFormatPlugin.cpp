#include "MeshFormatPlugin.hpp"

#include "isohex/core/Error.hpp"
#include "isohex/core/Plugin.hpp"

namespace isohex::io::detail {

const MeshFormatPlugin& meshFormatPlugin(Format format) {
    switch (format) {
        case Format::Vtu: return plugin::load<MeshFormatPlugin>("vtu", "reads and writes .vtu files with VTK");
        case Format::Msh: return plugin::load<MeshFormatPlugin>("msh", "reads and writes .msh files with Gmsh");
        case Format::Exodus:
            return plugin::load<MeshFormatPlugin>("exodus", "writes Exodus II files with libexodusII");
        case Format::Abaqus:
        case Format::Medit: break;
    }
    throw Error("internal: no plugin for this mesh format; isohex writes it itself");
}

}  // namespace isohex::io::detail

namespace isohex::io {

bool preloadFormat(const std::string& path) {
    try {
        const Format format = formatFromPath(path);
        if (format == Format::Vtu || format == Format::Msh || format == Format::Exodus)
            detail::meshFormatPlugin(format);
        return true;
    } catch (const Error&) {
        return false;
    }
}

}  // namespace isohex::io

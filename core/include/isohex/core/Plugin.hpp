#pragma once
// Plugins: the libraries that only some files need (VTK for .vtu, Gmsh for
// .msh, libexodusII for Exodus, ITK with GDCM and libtiff for image files)
// are loaded on first use from shared objects beside the program, so a run
// loads and initialises only what its own inputs and outputs need.
//
// Plugin `name` is the file libisohex_<name>.so in pluginFolder(). It exports
//     extern "C" const void* isohex_plugin_api();
// returning its table of functions, a struct whose first member is
// `int abi` (the struct's kAbi when the plugin was built). Plugins are
// loaded once, with every symbol bound at load, and never unloaded.
#include <filesystem>
#include <string>

#include "isohex/core/Error.hpp"

namespace isohex::plugin {

// $ISOHEX_PLUGIN_DIR if set, else <folder of the running executable>/../lib/isohex:
// bin/isohex -> lib/isohex when installed; build/cli/isohex (and the test
// programs in build/tests) -> build/lib/isohex in a build tree.
std::filesystem::path pluginFolder();

// The plugin's table, loaded on the first call. `purpose` says what it is
// for ("reads and writes .vtu files"). Throws Error naming the plugin file,
// the folder searched, the loader's reason and what to do when the file is
// missing or cannot be loaded.
const void* loadApi(const std::string& name, const std::string& purpose);

// The plugin's table as Api (a struct with `static constexpr int kAbi` and
// first member `int abi`); a plugin built from other sources is refused.
template <class Api>
const Api& load(const std::string& name, const std::string& purpose) {
    const auto* api = static_cast<const Api*>(loadApi(name, purpose));
    if (api->abi != Api::kAbi)
        throw Error("the plugin libisohex_" + name + ".so in " + pluginFolder().string() + " (" + purpose +
                    ") was built from other isohex sources (interface " + std::to_string(api->abi) + ", need " +
                    std::to_string(Api::kAbi) + "); install or build the program and its plugins together");
    return *api;
}

}  // namespace isohex::plugin

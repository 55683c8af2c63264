#include "isohex/core/Plugin.hpp"

#include <cstdlib>
#include <map>
#include <mutex>
#include <new>
#include <string>
#include <system_error>

#include <dlfcn.h>

namespace isohex::plugin {

std::filesystem::path pluginFolder() {
    if (const char* dir = std::getenv("ISOHEX_PLUGIN_DIR"); dir && *dir) return dir;
    std::error_code ec;
    const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (ec) throw Error("cannot find the isohex program's own file (/proc/self/exe: " + ec.message() +
                        ") to load its plugins; set ISOHEX_PLUGIN_DIR to the folder that holds libisohex_*.so");
    return (exe.parent_path() / ".." / "lib" / "isohex").lexically_normal();
}

const void* loadApi(const std::string& name, const std::string& purpose) {
    static std::mutex mutex;
    static std::map<std::string, const void*> loaded;
    const std::lock_guard<std::mutex> lock(mutex);
    if (auto it = loaded.find(name); it != loaded.end()) return it->second;

    const std::filesystem::path folder = pluginFolder();
    const std::string file = "libisohex_" + name + ".so";
    const std::filesystem::path path = folder / file;
    const std::string what = "the plugin " + file + " (" + purpose + ")";
    std::error_code ec;
    if (!std::filesystem::exists(path, ec))
        throw Error(what + " is missing: no " + path.string() +
                    ". Reinstall isohex with its lib/isohex folder, build it in a build tree with "
                    "`cmake --build BUILD --target isohex_plugins`, or set ISOHEX_PLUGIN_DIR to the folder that "
                    "holds it");
    // RTLD_NOW: a library the plugin needs that is missing or too old is an
    // error here, naming it, rather than a crash in the middle of a run.
    void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char* reason = dlerror();
        // The loader cannot map a library into an exhausted address space
        // (ulimit -v): that is running out of memory, reported as such by
        // the job's stage, not a broken installation.
        const std::string text = reason ? reason : "";
        if (text.find("failed to map segment") != std::string::npos ||
            text.find("Cannot allocate memory") != std::string::npos)
            throw std::bad_alloc();
        throw Error(what + " could not be loaded: " + boundedMessage(reason ? reason : "unknown reason") +
                    ". Install the Debian packages it needs (./setup.sh) or rebuild isohex");
    }
    using Entry = const void* (*)();
    auto entry = reinterpret_cast<Entry>(dlsym(handle, "isohex_plugin_api"));
    if (!entry)
        throw Error(path.string() + " is not an isohex plugin (it has no isohex_plugin_api); reinstall or rebuild "
                    "isohex");
    const void* api = entry();
    loaded.emplace(name, api);
    return api;
}

}  // namespace isohex::plugin

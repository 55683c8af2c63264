#include "isohex/core/AtomicFile.hpp"

#include <filesystem>
#include <random>
#include <system_error>

#include <unistd.h>

#include "isohex/core/Error.hpp"

namespace isohex::io {

namespace fs = std::filesystem;

void writeAtomically(const std::string& path, bool overwrite,
                     const std::function<void(const std::string&)>& produce) {
    const fs::path target(path);
    std::error_code ec;
    if (!overwrite && fs::exists(target, ec))
        throw Error(path + ": file exists; refusing to overwrite it (use --force to replace it)");
    fs::path dir = target.parent_path();
    if (dir.empty()) dir = ".";
    if (!fs::is_directory(dir, ec))
        throw Error(path + ": folder '" + dir.string() + "' does not exist; create it first");

    // Keep the real extension last: some libraries choose behaviour by it.
    std::random_device rd;
    const std::string tmpName = "." + target.stem().string() + ".tmp" + std::to_string(::getpid()) + "_" +
                                std::to_string(rd() % 1000000) + target.extension().string();
    const fs::path tmp = dir / tmpName;
    try {
        produce(tmp.string());
    } catch (...) {
        fs::remove(tmp, ec);
        throw;
    }
    if (!fs::exists(tmp, ec))
        throw Error(path + ": the writer produced no file");
    fs::rename(tmp, target, ec);
    if (ec) {
        fs::remove(tmp, ec);
        throw Error(path + ": could not move the finished file into place: " + ec.message());
    }
}

}  // namespace isohex::io

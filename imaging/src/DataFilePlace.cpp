// Where a header may point its voxel data (see DataFilePlace.hpp).
#include "DataFilePlace.hpp"

#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"

namespace fs = std::filesystem;

namespace isohex::imaging::detail {
namespace {

// What a path that exists but holds no voxel data is, or nullptr for a
// regular file.
const char* notARegularFile(const fs::file_status& s) {
    switch (s.type()) {
        case fs::file_type::regular: return nullptr;
        case fs::file_type::directory: return "a directory";
        case fs::file_type::character: return "a device";
        case fs::file_type::block: return "a device";
        case fs::file_type::fifo: return "a named pipe (FIFO)";
        case fs::file_type::socket: return "a socket";
        default: return "not a regular file";
    }
}

// True if `inner` is `outer` or lies below it (both canonical).
bool isWithin(const fs::path& inner, const fs::path& outer) {
    auto o = outer.begin();
    for (auto i = inner.begin(); o != outer.end(); ++i, ++o)
        if (i == inner.end() || *i != *o) return false;
    return true;
}

}  // namespace

fs::path checkDataFilePlace(const std::string& header, const std::string& named, bool allowOutside) {
    const fs::path dir = fs::path(header).parent_path();
    const fs::path data = dir / named;  // an absolute name replaces the folder
    const std::string start = header + ": its voxel data file '" + named + "'";
    std::error_code ec;
    const fs::file_status status = fs::status(data, ec);
    if (ec || !fs::exists(status))
        throw Error(start + " is missing (looked for " + data.string() +
                    "); keep the header and its data files together.");
    if (const char* what = notARegularFile(status)) {
        const std::string where = data.is_absolute() ? named : data.string();
        throw Error(start + " is " + (status.type() == fs::file_type::directory ? std::string() : where + ", ") + what +
                    ", not a file of voxels; fix the header to name the data file that belongs to it.");
    }
    if (fs::equivalent(data, header, ec))
        throw Error(start + " is the header itself; fix the header to name its data file (MetaImage: "
                    "ElementDataFile = LOCAL for data that follows the header in the same file).");
    if (!allowOutside) {
        const fs::path real = fs::canonical(data, ec);
        const fs::path home = fs::canonical(dir.empty() ? fs::path(".") : dir, ec);
        if (ec || !isWithin(real, home))
            throw SettingError({start + " is " + real.string() + ", outside the header's folder " + home.string() +
                                    "; isohex reads data files only in the header's folder or below it. Move the "
                                    "data next to the header, or, if you trust the header, allow it with the ",
                                Setting::AllowDataOutside, " option."});
    }
    return data;
}

}  // namespace isohex::imaging::detail

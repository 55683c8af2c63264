#include "Versions.hpp"

#include <sstream>

#include <CLI/Version.hpp>
#include <nlohmann/json.hpp>

#include "isohex/core/Version.hpp"
#include "isohex/imaging/Version.hpp"

namespace isohex::cli {

nlohmann::json versionsJson() {
    nlohmann::json v = coreVersions();
    v["cli11"] = CLI11_VERSION;
    const nlohmann::json imagingVersions = imaging::versions();  // a named object: items() only refers to it
    for (const auto& [name, ver] : imagingVersions.items()) v[name] = ver;
    return v;
}

std::string versionText() {
    std::ostringstream s;
    const nlohmann::json v = versionsJson();
    s << "isohex " << v["isohex"].get<std::string>() << "\nbuilt with";
    for (const auto& [name, ver] : v.items())
        if (name != "isohex") s << " " << name << " " << ver.get<std::string>();
    return s.str();
}

}  // namespace isohex::cli

#pragma once
#include <string>

#include <nlohmann/json_fwd.hpp>

namespace isohex::cli {
// "isohex X.Y.Z" plus the versions of the libraries it was built with.
std::string versionText();
nlohmann::json versionsJson();
}  // namespace isohex::cli

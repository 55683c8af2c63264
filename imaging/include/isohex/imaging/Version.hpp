#pragma once
#include <nlohmann/json_fwd.hpp>

namespace isohex::imaging {
// Versions of the libraries the imaging module reads scans with (ITK, OpenVDB, Assimp, OpenEXR).
nlohmann::json versions();
}  // namespace isohex::imaging

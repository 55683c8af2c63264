#include "isohex/imaging/Version.hpp"

#include <string>

#include <OpenEXR/OpenEXRConfig.h>
#include <itkConfigure.h>
#include <nlohmann/json.hpp>
#include <openvdb/version.h>

namespace isohex::imaging {

// Versions of the headers (Assimp's from its CMake package) isohex was built
// with: nothing here calls a library, so the launcher can print them without
// loading any (imaging/CMakeLists.txt).

nlohmann::json versions() {
    return {{"itk", ITK_VERSION_STRING "." + std::to_string(ITK_VERSION_PATCH)},
            {"openvdb", OPENVDB_LIBRARY_VERSION_STRING},
            {"assimp", ISOHEX_ASSIMP_VERSION},
            {"openexr", OPENEXR_VERSION_STRING}};
}

}  // namespace isohex::imaging

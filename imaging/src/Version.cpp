#include "isohex/imaging/Version.hpp"

#include <string>

#include <OpenEXR/OpenEXRConfig.h>
#include <assimp/version.h>
#include <itkConfigure.h>
#include <nlohmann/json.hpp>
#include <openvdb/version.h>

namespace isohex::imaging {

nlohmann::json versions() {
    return {{"itk", ITK_VERSION_STRING "." + std::to_string(ITK_VERSION_PATCH)},
            {"openvdb", OPENVDB_LIBRARY_VERSION_STRING},
            {"assimp", std::to_string(aiGetVersionMajor()) + "." + std::to_string(aiGetVersionMinor()) + "." +
                           std::to_string(aiGetVersionPatch())},
            {"openexr", OPENEXR_VERSION_STRING}};
}

}  // namespace isohex::imaging

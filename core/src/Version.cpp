#include "isohex/core/Version.hpp"

#include <string>

#include <Eigen/Core>
#include <exodusII.h>
#include <gmsh.h>
#include <netcdf_meta.h>
#include <nlohmann/json.hpp>
#include <oneapi/tbb/version.h>
#include <vtkVersionMacros.h>

namespace isohex {

// Versions of the headers isohex was compiled with: VTK, Gmsh and netCDF are
// only loaded by the plugins that need them (isohex/core/Plugin.hpp).

nlohmann::json coreVersions() {
    nlohmann::json v;
    v["isohex"] = ISOHEX_VERSION;
    v["tbb"] = TBB_runtime_version();
    v["eigen"] = std::to_string(EIGEN_WORLD_VERSION) + "." + std::to_string(EIGEN_MAJOR_VERSION) + "." +
                 std::to_string(EIGEN_MINOR_VERSION);
    v["vtk"] = VTK_VERSION;
    v["gmsh"] = GMSH_API_VERSION;
    v["exodusii"] = std::to_string(EX_API_VERS_NODOT / 100) + "." + std::to_string(EX_API_VERS_NODOT % 100 / 10) +
                    std::to_string(EX_API_VERS_NODOT % 10);
    v["netcdf"] = NC_VERSION;
    v["nlohmann_json"] = std::to_string(NLOHMANN_JSON_VERSION_MAJOR) + "." +
                         std::to_string(NLOHMANN_JSON_VERSION_MINOR) + "." +
                         std::to_string(NLOHMANN_JSON_VERSION_PATCH);
    return v;
}

}  // namespace isohex

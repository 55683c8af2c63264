#pragma once
#include <nlohmann/json_fwd.hpp>

namespace isohex {
// {"isohex": ..., "vtk": ..., "gmsh": ..., ...}: the versions core was built
// and linked with, for --version and reports.
nlohmann::json coreVersions();
}  // namespace isohex

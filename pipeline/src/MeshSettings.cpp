#include "isohex/pipeline/MeshSettings.hpp"

#include <string>

#include "isohex/core/SettingError.hpp"

namespace isohex::pipeline {

std::string_view methodName(Method method) {
    switch (method) {
        case Method::Dual: return "dual";
        case Method::Voxel: return "voxel";
        case Method::Sheets: return "sheets";
    }
    return "dual";
}

std::optional<Method> parseMethod(std::string_view name) {
    for (Method m : {Method::Dual, Method::Voxel, Method::Sheets})
        if (methodName(m) == name) return m;
    return std::nullopt;
}

void checkElementSize(const MeshSettings& settings) {
    if (settings.size && !(*settings.size > 0))
        throw SettingError(
            {Setting::Size, " must be a positive length in world units (got " + std::to_string(*settings.size) + ")"});
}

}  // namespace isohex::pipeline

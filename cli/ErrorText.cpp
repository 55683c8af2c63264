#include "ErrorText.hpp"

#include "MeshOptions.hpp"
#include "RunOptions.hpp"

namespace isohex::cli {

std::string nameOf(Setting s, SettingNames names) {
    if (s == Setting::Force) return flagOf(RunOption::Force);
    for (const MeshOption& o : meshOptions())
        if (o.setting == s) return names == SettingNames::Columns && o.columnHelp ? o.column() : o.flag();
    return std::string(settingName(s));
}

std::string userMessage(const std::exception& e, SettingNames names) {
    if (const auto* s = dynamic_cast<const SettingError*>(&e))
        return s->render([names](Setting x) { return nameOf(x, names); });
    return e.what();
}

}  // namespace isohex::cli

#pragma once
// The text of an error for the user. The libraries name the settings the
// user can change by kind (isohex::SettingError); the command line names
// them as its flags, a batch job as its manifest columns.
#include <exception>
#include <string>

#include "isohex/core/SettingError.hpp"

namespace isohex::cli {

enum class SettingNames { Flags, Columns };

// How `s` is named: "--size" (Flags) or "size" (Columns); a setting with
// no column (--force, an option of the whole run) is named as its flag.
std::string nameOf(Setting s, SettingNames names);

// e.what(), or for a SettingError its text with the settings named the
// `names` way.
std::string userMessage(const std::exception& e, SettingNames names);

}  // namespace isohex::cli

#pragma once
// The argument with which the isohex launcher asks isohex-run only to start:
// isohex-run returns 0 at the top of main, after the dynamic loader has loaded
// and initialised every library it links (launcher/Launcher.cpp says why).
#include <string_view>

namespace isohex::cli {
inline constexpr std::string_view kStartProbeFlag = "--start-probe";
}  // namespace isohex::cli

#pragma once
// A duration as people read it: "2.5 s", "45 s", "2.5 min", "3.2 h". For the
// progress line's and the terminal bar's time left, and a batch's pace.
#include <string>

namespace isohex::cli {

std::string durationText(double seconds);

}  // namespace isohex::cli

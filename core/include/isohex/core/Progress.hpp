#pragma once
// The progress callback every long stage takes: a stage name and the fraction
// of it done, in [0, 1]. It may be empty. Stages call it from the calling
// thread only, so a callback needs no locking.
#include <functional>
#include <string_view>

namespace isohex {

using Progress = std::function<void(std::string_view stage, double fraction)>;

}  // namespace isohex

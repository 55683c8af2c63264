#include "BatchPace.hpp"

#include <algorithm>

#include "DurationText.hpp"

namespace isohex::cli {

void BatchPace::jobRan(double seconds) {
    ++ran_;
    seconds_ += std::max(0.0, seconds);
}

std::optional<double> BatchPace::etaSeconds() const {
    if (ran_ == 0 || left() == 0) return std::nullopt;
    return seconds_ / static_cast<double>(ran_) * static_cast<double>(left());
}

std::string BatchPace::line() const {
    std::string s = std::to_string(ran_) + " of " + std::to_string(toRun_) + " jobs run in " + durationText(seconds_);
    if (const auto eta = etaSeconds()) s += "; about " + durationText(*eta) + " left at this pace";
    return s;
}

}  // namespace isohex::cli

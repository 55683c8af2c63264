#include "ProgressModel.hpp"

#include <algorithm>
#include <utility>

namespace isohex::cli {

std::vector<std::string> ProgressModel::defaultPlan() {
    return {"load", "select", "octree", "extract", "pillow", "optimize", "fidelity", "write"};
}

// Shares of a typical run's time (bench/RESULTS.md: optimisation is most of
// it). The boundary relaxation runs only where hexes stay below the certified
// minimum, so it is not planned; when it runs it adds its share, about a tenth
// of a scan's run (ch2bet at 1.25 mm: optimize 14.2 s, relax 1.8 s of 20.2 s).
// A local meshing again (pipeline/LocalRetry.hpp: "extract_again",
// "pillow_again", "optimize_again") adds 2 per stage: about 4% of ch2bet's
// default run (`isohex mesh ch2bet.nii.gz`: 0.52 + 0.51 + 0.00 s of 26.2 s).
double ProgressModel::weight(std::string_view stage) {
    if (stage == "optimize") return 70;
    if (stage == "relax") return 8;
    if (stage == "sheets") return 20;
    if (stage == "octree" || stage == "worst_hexes") return 5;
    if (stage == "load" || stage == "extract" || stage == "quality") return 3;
    if (stage == "select" || stage == "pillow" || stage == "grid" || stage == "dice") return 1;
    return 2;
}

ProgressModel::ProgressModel(std::vector<std::string> planned, std::map<std::string, double> weights)
    : plan_(std::move(planned)), weights_(std::move(weights)) {
    for (const auto& s : plan_) planned_ += weightOf(s);
}

double ProgressModel::weightOf(const std::string& stage) const {
    const auto it = weights_.find(stage);
    return it != weights_.end() ? it->second : weight(stage);
}

bool ProgressModel::takePlanned(const std::string& stage) {
    const auto from = plan_.begin() + static_cast<std::ptrdiff_t>(nextPlanned_);
    const auto it = std::find(from, plan_.end(), stage);
    if (it == plan_.end()) return false;
    // What was passed over is done with, and so are the repeats a retry
    // planned that did not run (a feature removal's neighbourhood needs no
    // relaxation again): the bar moves on by their share.
    for (auto k = from; k != it; ++k) planned_ -= weightOf(*k);
    for (const std::string& r : repeats_) planned_ -= repeatWeight_[r];
    repeats_.clear();
    nextPlanned_ = static_cast<std::size_t>(it - plan_.begin()) + 1;
    return true;
}

double ProgressModel::raw() const {
    if (!(planned_ > 0)) return 0;
    return std::clamp((done_ + currentWeight_ * fraction_) / planned_, 0.0, 1.0);
}

void ProgressModel::update() {
    const double r = raw();
    const double span = 1 - anchorRaw_;
    const double s = span > 0 ? anchorShown_ + (1 - anchorShown_) * std::max(0.0, r - anchorRaw_) / span : 1.0;
    shown_ = std::clamp(std::max(shown_, s), 0.0, 1.0);
}

// More work than planned: the bar keeps what it shows and spreads the rest
// over the new plan.
void ProgressModel::grow(double more) {
    update();
    planned_ += more;
    anchorShown_ = shown_;
    anchorRaw_ = raw();
}

void ProgressModel::begin(std::string_view stage) {
    const std::string s(stage);
    current_ = s;
    fraction_ = 0;
    currentWeight_ = weightOf(s);
    const auto first = std::find(order_.begin(), order_.end(), s);
    if (takePlanned(s)) {
        if (first == order_.end()) order_.push_back(s);
    } else if (first == order_.end()) {
        order_.push_back(s);
        grow(weightOf(s));  // a stage outside the plan adds its own weight
    } else if (const auto r = repeats_.find(s); r != repeats_.end()) {
        repeats_.erase(r);  // its repeat is in the plan already
        currentWeight_ = repeatWeight_[s];
    } else if (ended_.count(s)) {
        // A repeat: the stages from this one to the last that ended run
        // again, each about as long as the first time.
        const double rate = endedSeconds_ > 0 ? done_ / endedSeconds_ : 0;
        const auto last = std::find(order_.begin(), order_.end(), lastEnded_);
        double more = 0;
        for (auto it = first; it != order_.end() && it <= last; ++it) {
            const auto secs = firstSeconds_.find(*it);
            const double w = rate > 0 && secs != firstSeconds_.end() ? rate * secs->second : weightOf(*it);
            more += w;
            if (it == first) {
                currentWeight_ = w;
            } else {
                repeats_.insert(*it);
                repeatWeight_[*it] = w;
            }
        }
        grow(more);
    }
    update();
}

void ProgressModel::progress(double fraction) {
    fraction_ = std::clamp(fraction, 0.0, 1.0);
    update();
}

void ProgressModel::end(std::string_view stage, double seconds) {
    const std::string s(stage);
    done_ += s == current_ ? currentWeight_ : weightOf(s);
    endedSeconds_ += std::max(0.0, seconds);
    firstSeconds_.emplace(s, std::max(0.0, seconds));
    fraction_ = 0;
    currentWeight_ = 0;
    current_.clear();
    ended_.insert(s);
    lastEnded_ = s;
    update();
}

std::optional<double> ProgressModel::eta(double elapsed) const {
    const double r = raw();
    if (r < 0.02 || r >= 1) return std::nullopt;
    return elapsed * (1 - r) / r;
}

}  // namespace isohex::cli

#pragma once
// The whole run's progress from its stages': each stage has a weight (its
// usual share of a run's time). The plan lists the stages expected in order,
// a stage as often as it runs (compare optimises each variant); a planned
// stage passed over (the optimiser with --no-optimize) leaves the plan when a
// later one begins, and so does a retry's repeat that did not run. A stage
// that begins again outside the plan (a retry meshes again) adds the stages
// it repeats to the plan, each weighted by the time it took the first time
// (at the run's rate of weight per second so far), and what is left of the
// bar is spread over the larger plan: the fraction shown never goes down.
// The ETA comes from the plan itself (done against planned weight), so it
// covers the repeats from the moment they begin.
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace isohex::cli {

class ProgressModel {
public:
    // `planned`: the stages expected, in order (the mesh pipeline's by
    // default); `weights`: a command's own weights where they differ from weight().
    explicit ProgressModel(std::vector<std::string> planned = defaultPlan(), std::map<std::string, double> weights = {});
    static std::vector<std::string> defaultPlan();
    static double weight(std::string_view stage);

    void begin(std::string_view stage);
    void progress(double fraction);  // of the current stage, clamped to [0, 1]
    void end(std::string_view stage, double seconds);
    // The run's fraction done: never lower than any value returned before.
    double overall() const { return shown_; }
    // Seconds left, from `elapsed` seconds since the run began (none below 2%).
    std::optional<double> eta(double elapsed) const;

private:
    double raw() const;  // done weight over planned weight
    void update();
    void grow(double more);
    double weightOf(const std::string& stage) const;  // weights_ or weight()
    // Takes the next planned occurrence of `stage`, passing over the planned
    // stages before it that never began; false if the rest of the plan has none.
    bool takePlanned(const std::string& stage);

    std::vector<std::string> plan_;   // the stages expected
    std::size_t nextPlanned_ = 0;     // the first entry of plan_ not yet begun or passed over
    std::map<std::string, double> weights_;
    std::vector<std::string> order_;  // stages in the order they first began
    std::set<std::string> ended_;      // stages that have ended at least once
    std::multiset<std::string> repeats_;  // repeats already added to the plan, not yet begun
    std::map<std::string, double> firstSeconds_;  // each stage's time the first time it ran
    std::map<std::string, double> repeatWeight_;  // the weight planned for a pending repeat
    std::string current_, lastEnded_;
    double planned_ = 0, done_ = 0, fraction_ = 0, currentWeight_ = 0, endedSeconds_ = 0;
    double shown_ = 0, anchorShown_ = 0, anchorRaw_ = 0;  // shown = anchorShown + (1 - anchorShown) * progress since anchor
};

}  // namespace isohex::cli

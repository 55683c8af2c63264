#pragma once
// Draws pipeline progress on stderr: a bar of the whole run (ProgressModel:
// never backwards, retries included) with the stage, elapsed time and ETA on
// a terminal, plain periodic lines otherwise, one JSON object per event with
// --log-json (stage events and progress carry the run's "overall" fraction
// and "eta_s"), nothing with --quiet (warnings still print).
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "ProgressModel.hpp"
#include "isohex/core/Stopwatch.hpp"
#include "isohex/pipeline/StageSink.hpp"

namespace isohex::cli {

// Writes all of `text` to the file descriptor (retrying after signals and
// short writes); false if the descriptor refuses it. A line written this way
// is one write when the descriptor takes it whole, so lines of two processes
// sharing stderr do not interleave.
bool writeAll(int fd, std::string_view text);

class ProgressSink : public pipeline::StageSink {
public:
    enum class Mode { Auto, Quiet, Json };
    // `plan` and `weights`: the stages the run expects and their weights
    // (ProgressModel), the mesh pipeline's by default.
    explicit ProgressSink(Mode mode, std::string job = {}, std::vector<std::string> plan = ProgressModel::defaultPlan(),
                          std::map<std::string, double> weights = {});
    void begin(std::string_view stage) override;
    void progress(double fraction) override;
    void end(std::string_view stage, double seconds) override;
    void note(std::string_view level, const std::string& text) override;
    void reading(const std::string& file) override;  // tells the job isolation (nowReading)
    void event(const std::string& name, const nlohmann::json& fields);  // JSON mode only
    void setJob(std::string job) { job_ = std::move(job); }
    Mode mode() const { return mode_; }
    // Seconds per finished stage (a stage run twice adds up).
    const nlohmann::json& timings() const { return timings_; }

private:
    void drawBar(bool final);
    nlohmann::json overallFields() const;  // the run's fraction and ETA for JSON events
    Mode mode_;
    bool terminal_ = false;
    std::string job_;
    std::string stage_;
    double fraction_ = 0;
    Stopwatch sinceStageBegan_, sinceDrawn_, sinceRunBegan_;
    bool runBegan_ = false;
    ProgressModel model_;
    std::mutex mutex_;
    nlohmann::json timings_ = nlohmann::json::object();
};

}  // namespace isohex::cli

#include "Progress.hpp"

#include "DurationText.hpp"
#include "JobStage.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <iostream>

#include <unistd.h>

namespace isohex::cli {

namespace {
double wallClock() {
    return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}
}  // namespace

bool writeAll(int fd, std::string_view text) {
    std::size_t done = 0;
    while (done < text.size()) {
        const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return false;
        done += static_cast<std::size_t>(n);
    }
    return true;
}

ProgressSink::ProgressSink(Mode mode, std::string job, std::vector<std::string> plan,
                           std::map<std::string, double> weights)
    : mode_(mode), job_(std::move(job)), model_(std::move(plan), std::move(weights)) {
    terminal_ = mode == Mode::Auto && ::isatty(STDERR_FILENO);
}

void ProgressSink::event(const std::string& name, const nlohmann::json& fields) {
    if (mode_ != Mode::Json) return;
    nlohmann::json j = fields;
    j["event"] = name;
    j["time"] = wallClock();
    if (!job_.empty()) j["job"] = job_;
    // One write per event line: a meshing process killed between the object
    // and its newline left the next event glued to it.
    std::cerr.flush();
    writeAll(STDERR_FILENO, j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
}

nlohmann::json ProgressSink::overallFields() const {
    nlohmann::json j = {{"overall", model_.overall()}};
    if (const auto eta = model_.eta(sinceRunBegan_.seconds())) j["eta_s"] = *eta;
    return j;
}

void ProgressSink::begin(std::string_view stage) {
    stageBegins(stage);
    std::lock_guard lock(mutex_);
    if (!runBegan_) {
        runBegan_ = true;
        sinceRunBegan_.restart();
    }
    stage_ = stage;
    fraction_ = 0;
    model_.begin(stage);
    sinceStageBegan_.restart();
    sinceDrawn_.restart();
    if (mode_ == Mode::Json) {
        nlohmann::json j = overallFields();
        j["stage"] = stage_;
        event("stage_begin", j);
    }
    else if (terminal_) drawBar(false);
}

void ProgressSink::reading(const std::string& file) { nowReading(file); }

void ProgressSink::progress(double fraction) {
    std::lock_guard lock(mutex_);
    // A stage's own fraction never goes back either (the plain lines print it).
    fraction_ = std::max(fraction_, std::clamp(fraction, 0.0, 1.0));
    model_.progress(fraction_);
    const double sinceDrawn = sinceDrawn_.seconds();
    if (mode_ == Mode::Json) {
        if (sinceDrawn >= 1.0) {
            sinceDrawn_.restart();
            nlohmann::json j = overallFields();
            j["stage"] = stage_;
            j["fraction"] = fraction_;
            event("progress", j);
        }
    } else if (terminal_) {
        if (sinceDrawn >= 0.1) {
            sinceDrawn_.restart();
            drawBar(false);
        }
    } else if (mode_ == Mode::Auto && sinceDrawn >= 5.0) {
        sinceDrawn_.restart();
        std::string left;
        if (const auto eta = model_.eta(sinceRunBegan_.seconds())) left = ", about " + durationText(*eta) + " left";
        std::fprintf(stderr, "isohex: %s%s%s %3.0f%% (%.1f s; run %.0f%%%s)\n", job_.c_str(), job_.empty() ? "" : ": ",
                     stage_.c_str(), 100 * fraction_, sinceStageBegan_.seconds(), 100 * model_.overall(),
                     left.c_str());
    }
}

void ProgressSink::end(std::string_view stage, double secs) {
    std::lock_guard lock(mutex_);
    fraction_ = 1;
    const std::string key(stage);
    timings_[key] = timings_.value(key, 0.0) + secs;
    model_.end(stage, secs);
    if (mode_ == Mode::Json) {
        nlohmann::json j = overallFields();
        j["stage"] = key;
        j["seconds"] = secs;
        event("stage_end", j);
    }
    else if (terminal_) drawBar(true);
    else if (mode_ == Mode::Auto)
        std::fprintf(stderr, "isohex: %s%s%-8s done in %.2f s\n", job_.c_str(), job_.empty() ? "" : ": ",
                     std::string(stage).c_str(), secs);
}

void ProgressSink::note(std::string_view level, const std::string& text) {
    std::lock_guard lock(mutex_);
    if (mode_ == Mode::Json) {
        event(std::string(level), {{"message", text}});
        return;
    }
    if (mode_ == Mode::Quiet && level != "warning" && level != "error") return;
    if (terminal_) std::fputs("\r\033[K", stderr);
    std::fprintf(stderr, "isohex: %s%s%s: %s\n", job_.c_str(), job_.empty() ? "" : ": ", std::string(level).c_str(),
                 text.c_str());
}

// The bar and its percentage are the whole run's (they never go back, also
// when a retry meshes again); the stage's own time follows its name.
void ProgressSink::drawBar(bool final) {
    const double overall = model_.overall();
    constexpr int width = 30;
    const int filled = static_cast<int>(overall * width + 0.5);
    std::string bar(static_cast<std::size_t>(filled), '#');
    bar.resize(width, '.');
    std::string eta;
    if (const auto left = model_.eta(sinceRunBegan_.seconds()); left && !final) eta = "  ETA " + durationText(*left);
    std::fprintf(stderr, "\r\033[K%-9s [%s] %3.0f%%  %.1f s%s%s", stage_.c_str(), bar.c_str(), 100 * overall,
                 sinceStageBegan_.seconds(), eta.c_str(), final ? "\n" : "");
    std::fflush(stderr);
}

}  // namespace isohex::cli

#include "Progress.hpp"

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

ProgressSink::ProgressSink(Mode mode, std::string job) : mode_(mode), job_(std::move(job)) {
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

void ProgressSink::begin(std::string_view stage) {
    stageBegins(stage);
    std::lock_guard lock(mutex_);
    stage_ = stage;
    fraction_ = 0;
    sinceStageBegan_.restart();
    sinceDrawn_.restart();
    if (mode_ == Mode::Json) event("stage_begin", {{"stage", stage_}});
    else if (terminal_) drawBar(false);
}

void ProgressSink::reading(const std::string& file) { nowReading(file); }

void ProgressSink::progress(double fraction) {
    std::lock_guard lock(mutex_);
    fraction_ = std::clamp(fraction, 0.0, 1.0);
    const double sinceDrawn = sinceDrawn_.seconds();
    if (mode_ == Mode::Json) {
        if (sinceDrawn >= 1.0) {
            sinceDrawn_.restart();
            event("progress", {{"stage", stage_}, {"fraction", fraction_}});
        }
    } else if (terminal_) {
        if (sinceDrawn >= 0.1) {
            sinceDrawn_.restart();
            drawBar(false);
        }
    } else if (mode_ == Mode::Auto && sinceDrawn >= 5.0) {
        sinceDrawn_.restart();
        std::fprintf(stderr, "isohex: %s%s%s %3.0f%% (%.1f s)\n", job_.c_str(), job_.empty() ? "" : ": ", stage_.c_str(),
                     100 * fraction_, sinceStageBegan_.seconds());
    }
}

void ProgressSink::end(std::string_view stage, double secs) {
    std::lock_guard lock(mutex_);
    fraction_ = 1;
    const std::string key(stage);
    timings_[key] = timings_.value(key, 0.0) + secs;
    if (mode_ == Mode::Json) event("stage_end", {{"stage", std::string(stage)}, {"seconds", secs}});
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

void ProgressSink::drawBar(bool final) {
    const double elapsed = sinceStageBegan_.seconds();
    constexpr int width = 30;
    const int filled = static_cast<int>(fraction_ * width + 0.5);
    std::string bar(static_cast<std::size_t>(filled), '#');
    bar.resize(width, '.');
    char eta[32] = "";
    if (!final && fraction_ > 0.02) std::snprintf(eta, sizeof eta, "  ETA %.1f s", elapsed * (1 - fraction_) / fraction_);
    std::fprintf(stderr, "\r\033[K%-9s [%s] %3.0f%%  %.1f s%s%s", stage_.c_str(), bar.c_str(), 100 * fraction_, elapsed,
                 eta, final ? "\n" : "");
    std::fflush(stderr);
}

}  // namespace isohex::cli

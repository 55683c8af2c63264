#include "JobStage.hpp"

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <cstring>

#include <sys/mman.h>

namespace isohex::cli {

namespace {

StageSlot* gSlot = nullptr;  // set in the child of an isolated job only
std::string gInput;          // the job's input, for ISOHEX_TEST_CRASH=...@text (isolated or not)

void copyInto(char* slot, std::size_t size, std::string_view text) {
    const std::size_t n = std::min(text.size(), size - 1);
    std::memcpy(slot, text.data(), n);
    slot[n] = '\0';
}

// ISOHEX_TEST_CRASH=<stage>[:kill][@<text>]: see stageBegins.
void injectedFault(std::string_view stage, const std::string& subject) {
    const char* crash = std::getenv("ISOHEX_TEST_CRASH");
    if (!crash) return;
    std::string c(crash), only;
    if (const auto at = c.find('@'); at != std::string::npos) {
        only = c.substr(at + 1);
        c.resize(at);
    }
    if (!only.empty() && subject.find(only) == std::string::npos) return;
    if (c == stage) std::raise(SIGSEGV);
    if (c == std::string(stage) + ":kill") std::raise(SIGKILL);
}

}  // namespace

StageSlot* sharedStageSlot() {
    static StageSlot* slot = [] {
        void* p = ::mmap(nullptr, sizeof(StageSlot), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
        return p == MAP_FAILED ? nullptr : static_cast<StageSlot*>(p);
    }();
    return slot;
}

void jobStarts(const std::string& input) { gInput = input; }

void recordStagesIn(StageSlot* slot) { gSlot = slot; }

void stageBegins(std::string_view stage) {
    if (gSlot) {
        copyInto(gSlot->stage, sizeof gSlot->stage, stage);
        gSlot->file[0] = '\0';
    }
    injectedFault(stage, gInput);
}

void nowReading(const std::string& file) {
    if (gSlot) {
        copyInto(gSlot->stage, sizeof gSlot->stage, "load");
        copyInto(gSlot->file, sizeof gSlot->file, file);
    }
    injectedFault("load", file);
}

}  // namespace isohex::cli

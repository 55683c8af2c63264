#include "isohex/core/AtomicFile.hpp"

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <system_error>

#include <unistd.h>

#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"

namespace isohex::io {

namespace fs = std::filesystem;

namespace {

// Temporaries being written, for the signal handler: fixed slots (a handler
// may not allocate or lock). A slot is free (0), being filled (1) or holds a
// path the handler removes (2).
constexpr int kSlots = 32;
constexpr std::size_t kPathMax = 4096;
char gTemporary[kSlots][kPathMax];
std::atomic<int> gState[kSlots];

int claimSlot(const std::string& path) {
    if (path.size() >= kPathMax) return -1;
    for (int i = 0; i < kSlots; ++i) {
        int expected = 0;
        if (gState[i].compare_exchange_strong(expected, 1)) {
            std::memcpy(gTemporary[i], path.c_str(), path.size() + 1);
            gState[i].store(2);
            return i;
        }
    }
    return -1;  // more writes at once than slots: that one is not cleaned up
}

void releaseSlot(int i) {
    if (i >= 0) gState[i].store(0);
}

extern "C" void removeTemporariesAndExit(int sig) {
    for (int i = 0; i < kSlots; ++i)
        if (gState[i].load() == 2) ::unlink(gTemporary[i]);
    std::signal(sig, SIG_DFL);
    std::raise(sig);
}

// A writer that fails on a full disk rarely says so: VTK's XML writer reports
// "returned failure for request", Exodus "ex_put_conn failed". So a failed
// write asks the disk itself, while the partial file still fills it.
bool diskFull(const fs::path& folder) {
    constexpr std::uintmax_t kNearlyFull = std::uintmax_t{4} << 20;
    std::error_code ec;
    const fs::space_info space = fs::space(folder, ec);
    return !ec && space.available <= kNearlyFull;
}

}  // namespace

int removeOnSignal(const std::string& path) {
    std::error_code ec;
    return claimSlot(fs::absolute(fs::path(path), ec).string());
}

void releaseOnSignal(int handle) { releaseSlot(handle); }

void removeTemporariesOnSignal() {
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
        // A signal the caller ignores stays ignored: `nohup isohex batch ...`
        // must survive the hangup it was started to survive.
        struct sigaction current {};
        if (sigaction(sig, nullptr, &current) == 0 && current.sa_handler == SIG_IGN) continue;
        struct sigaction sa {};
        sa.sa_handler = removeTemporariesAndExit;
        sigemptyset(&sa.sa_mask);
        sa.sa_flags = SA_RESETHAND;
        sigaction(sig, &sa, nullptr);
    }
}

std::string temporaryPrefix(const std::string& path, long pid) {
    return "." + fs::path(path).stem().string() + ".tmp" + std::to_string(pid) + "_";
}

void writeAtomically(const std::string& path, bool overwrite,
                     const std::function<void(const std::string&)>& produce) {
    const fs::path target(path);
    std::error_code ec;
    if (!overwrite && fs::exists(target, ec))
        throw SettingError({path + ": file exists; refusing to overwrite it (use ", Setting::Force, " to replace it)"});
    fs::path dir = target.parent_path();
    if (dir.empty()) dir = ".";
    if (!fs::is_directory(dir, ec))
        throw Error(path + ": folder '" + dir.string() + "' does not exist; create it first");

    // Keep the real extension last: some libraries choose behaviour by it.
    std::random_device rd;
    const std::string tmpName =
        temporaryPrefix(path, ::getpid()) + std::to_string(rd() % 1000000) + target.extension().string();
    const fs::path tmp = dir / tmpName;
    const int slot = claimSlot(fs::absolute(tmp, ec).string());
    auto discard = [&] {
        fs::remove(tmp, ec);
        releaseSlot(slot);
    };
    try {
        produce(tmp.string());
    } catch (const SettingError&) {
        discard();
        throw;
    } catch (const Error& e) {
        const bool full = diskFull(dir);  // before the partial file goes
        discard();
        if (!full) throw;
        throw DiskFullError(std::string(e.what()) + " (the disk holding '" + dir.string() +
                                "' ran out of space while writing it: free some space there or write to another disk)",
                            dir.string());
    } catch (...) {
        discard();
        throw;
    }
    if (!fs::exists(tmp, ec)) {
        releaseSlot(slot);
        throw Error(path + ": the writer produced no file");
    }
    fs::rename(tmp, target, ec);
    releaseSlot(slot);
    if (ec) {
        fs::remove(tmp, ec);
        throw Error(path + ": could not move the finished file into place: " + ec.message());
    }
}

void writeTextAtomically(const std::string& path, bool overwrite, const std::string& text) {
    writeAtomically(path, overwrite, [&](const std::string& tmp) {
        std::ofstream f(tmp);
        if (!f) throw Error(path + ": cannot write here (permission denied or read-only folder)");
        f << text;
        errno = 0;
        f.close();
        if (!f) throw Error(path + ": write failed" + (errno ? std::string(": ") + std::strerror(errno) : std::string()));
    });
}

}  // namespace isohex::io

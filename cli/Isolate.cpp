#include "Isolate.hpp"

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iostream>
#include <new>
#include <stdexcept>
#include <system_error>
#include <string>
#include <variant>
#include <vector>

#include <fcntl.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "JobStage.hpp"
#include "Progress.hpp"
#include "isohex/core/AtomicFile.hpp"
#include "isohex/core/DiskFullError.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"

namespace isohex::cli {

namespace fs = std::filesystem;

namespace {

// While the parent waits: SIGINT, SIGTERM and SIGHUP go on to the child,
// whose own handler removes the files it was writing; the parent raises the
// signal on itself once the child has ended, so a batch stops there as
// before and the caller sees the same signal.
volatile sig_atomic_t gChild = 0;
volatile sig_atomic_t gForwarded = 0;
constexpr int kForwarded[] = {SIGINT, SIGTERM, SIGHUP};

extern "C" void forwardToChild(int sig) {
    gForwarded = sig;
    if (gChild > 0) ::kill(static_cast<pid_t>(gChild), sig);
}

bool isolationOn() {
    const char* e = std::getenv("ISOHEX_ISOLATE");
    return !(e && std::string(e) == "0");
}

std::string signalName(int sig) {
    switch (sig) {
        case SIGSEGV: return "SIGSEGV, segmentation fault";
        case SIGABRT: return "SIGABRT, aborted";
        case SIGBUS: return "SIGBUS, bus error";
        case SIGFPE: return "SIGFPE, arithmetic exception";
        case SIGILL: return "SIGILL, illegal instruction";
        case SIGKILL: return "SIGKILL";
        case SIGTERM: return "SIGTERM";
        case SIGINT: return "SIGINT";
        case SIGHUP: return "SIGHUP";
        case SIGPIPE: return "SIGPIPE, broken pipe";
        case SIGXFSZ: return "SIGXFSZ, file size limit exceeded";
        case SIGXCPU: return "SIGXCPU, CPU time limit exceeded";
        default: {
            const char* d = ::strsignal(sig);
            return "signal " + std::to_string(sig) + (d ? std::string(", ") + d : std::string());
        }
    }
}

// A failed allocation, said with the stage and the limit that caused it.
std::string outOfMemoryText(const std::string& input, const std::string& where) {
    return input + ": out of memory " + where + memoryLimitText() +
           "; try a coarser --size or a lower --max-memory, raise the limit, or use a machine with more memory";
}

// What the parent says about a child that ended without a result.
std::string describeEnd(const std::string& job, int status, const std::string& stage, const std::string& file) {
    const std::string& input = file.empty() ? job : file;
    const std::string where = stage.empty() ? "before its first stage" : "in its " + stage + " stage";
    if (WIFSIGNALED(status)) {
        const int sig = WTERMSIG(status);
        const std::string name = signalName(sig);
        if (sig == SIGKILL)
            return input + ": the meshing process was killed (" + name + ") " + where +
                   ". The kernel's out-of-memory killer does this when memory runs out: try a coarser --size, a "
                   "lower --max-memory, or a machine with more memory.";
        if (sig == SIGXFSZ)
            return input + ": the meshing process was stopped (" + name + ") " + where +
                   ": a file reached the size limit (ulimit -f); raise the limit or write elsewhere.";
        if (sig == SIGXCPU)
            return input + ": the meshing process was stopped (" + name + ") " + where +
                   ": it reached the CPU time limit (ulimit -t).";
        const bool crash = sig == SIGSEGV || sig == SIGABRT || sig == SIGBUS || sig == SIGFPE || sig == SIGILL ||
                           sig == SIGSYS || sig == SIGTRAP;
        if (!crash) return input + ": the meshing process was stopped (" + name + ") " + where + ".";
        // Under ulimit -v a library that cannot allocate where it cannot
        // throw (a constructor of a static, a thread start) aborts.
        if (sig == SIGABRT && !memoryLimitText().empty())
            return outOfMemoryText(input, where) + " (a library aborted when an allocation failed)";
        if (stage == "load")
            return input + ": a library crashed reading it (" + name +
                   "); the file is probably damaged (OpenVDB, for one, does not check a .vdb's grid data). "
                   "Write or export it again; if it opens in other programs, please report this with the file.";
        return input + ": isohex crashed " + where + " (" + name +
               "). This is a bug: please report it with the command line and the input.";
    }
    return input + ": the meshing process ended with exit status " + std::to_string(WEXITSTATUS(status)) +
           " " + where + " without a result.";
}

// After a child died: the files it created (not the ones that existed before
// the job) and its temporaries (io::temporaryPrefix, beside the target) are
// removed.
void removeLeftovers(const std::vector<std::string>& files, const std::vector<bool>& existed, pid_t child) {
    std::error_code ec;
    for (std::size_t i = 0; i < files.size(); ++i) {
        const fs::path target(files[i]);
        if (!existed[i]) fs::remove(target, ec);
        const fs::path dir = target.parent_path().empty() ? fs::path(".") : target.parent_path();
        const std::string prefix = io::temporaryPrefix(files[i], child);
        for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
            const std::string name = it->path().filename().string();
            if (name.compare(0, prefix.size(), prefix) == 0) fs::remove(it->path(), ec);
        }
    }
}


void flushAll() {
    std::cout.flush();
    std::cerr.flush();
    std::fflush(nullptr);
}

[[noreturn]] void childMain(const std::function<nlohmann::json()>& work, int fd, pid_t parent) {
    // End with the parent: a batch manager's SIGTERM to isohex must not leave
    // an orphan meshing on.
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (::getppid() != parent) ::_exit(1);
    nlohmann::json msg;
    try {
        msg = {{"result", work()}};
    } catch (const io::DiskFullError& e) {
        msg = {{"error", "disk_full"}, {"message", bytesOf(e.what())}, {"folder", bytesOf(e.folder())}};
    } catch (const SettingError& e) {
        // the settings by kind: the parent names them as its front end does
        nlohmann::json parts = nlohmann::json::array();
        for (const MessagePart& p : e.parts())
            parts.push_back(std::holds_alternative<Setting>(p) ? nlohmann::json{{"setting", static_cast<int>(std::get<Setting>(p))}}
                                                               : nlohmann::json{{"text", bytesOf(std::get<std::string>(p))}});
        msg = {{"error", "user"}, {"message", bytesOf(e.what())}, {"parts", parts}};
    } catch (const Error& e) {
        msg = {{"error", "user"}, {"message", bytesOf(e.what())}};
    } catch (const std::bad_alloc&) {
        msg = nullptr;
    } catch (const std::system_error& e) {
        // a thread that could not start (TBB, std::thread) for want of memory
        if (e.code() == std::errc::resource_unavailable_try_again || e.code() == std::errc::not_enough_memory)
            msg = nullptr;
        else
            msg = {{"error", "internal"}, {"message", bytesOf(e.what())}};
    } catch (const std::exception& e) {
        msg = {{"error", "internal"}, {"message", bytesOf(e.what())}};
    }
    // Out of memory (null above), or no memory left to say otherwise: a
    // message that needs no allocation.
    std::string text;
    try {
        if (!msg.is_null()) text = msg.dump();
    } catch (...) {
        text.clear();
    }
    // The work is done (its outputs in place) or has failed cleanly: from
    // here no forwarded signal or closed stdout may turn that into a death
    // without a result, which the parent would report as a crash and clean
    // up after. (The parent re-raises a forwarded signal itself.)
    sigset_t quiet;
    sigemptyset(&quiet);
    for (int sig : kForwarded) sigaddset(&quiet, sig);
    ::sigprocmask(SIG_BLOCK, &quiet, nullptr);
    std::signal(SIGPIPE, SIG_IGN);
    flushAll();
    const bool sent = text.empty() ? writeAll(fd, R"({"error":"memory"})") : writeAll(fd, text);
    ::close(fd);
    ::_exit(sent ? 0 : 1);
}

// The error a child sent, thrown in the parent as the same kind; running out
// of memory names the stage and file the child was at.
[[noreturn]] void rethrowChildError(const nlohmann::json& msg, const std::string& input, const StageSlot& slot) {
    const std::string kind = msg.value("error", "internal");
    if (kind == "user" && msg.contains("parts")) {
        std::vector<MessagePart> parts;
        for (const auto& p : msg["parts"]) {
            if (p.contains("setting")) parts.emplace_back(static_cast<Setting>(p["setting"].get<int>()));
            else parts.emplace_back(textOf(p["text"]));
        }
        throw SettingError(std::move(parts));
    }
    if (kind == "user") throw Error(textOf(msg["message"]));
    if (kind == "disk_full") throw io::DiskFullError(textOf(msg["message"]), textOf(msg["folder"]));
    if (kind == "memory") {
        const std::string stage(slot.stage), file(slot.file);
        throw Error(outOfMemoryText(file.empty() ? input : file,
                                    stage.empty() ? "before its first stage" : "in its " + stage + " stage"));
    }
    throw std::runtime_error(textOf(msg["message"]));
}

}  // namespace

nlohmann::json runIsolated(const std::string& input, const std::vector<std::string>& files,
                           const std::function<nlohmann::json()>& work) {
    jobStarts(input);
    if (!isolationOn()) return work();
    // Without its own process a job that crashes would end isohex (and a
    // batch), and its threads would stay in the process later jobs fork
    // from: say so instead of running it here.
    auto cannotStart = [&](const char* what) {
        return Error(input + ": cannot start the process for this job (" + what + ": " + std::strerror(errno) +
                     "); the machine is out of processes or memory. Retry when it has some to spare.");
    };
    StageSlot* slot = sharedStageSlot();
    if (slot == nullptr) throw cannotStart("mmap");
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) throw cannotStart("pipe");
    std::vector<bool> existed;
    for (const auto& f : files) {
        std::error_code ec;
        existed.push_back(fs::exists(fs::symlink_status(f, ec)));  // a dangling link is there too
    }
    flushAll();  // else the child would print the parent's buffered output again
    // The forwarding handlers are in place before the fork, with the signals
    // held until each side has set itself up: the child goes back to the
    // handlers it inherited (which remove its temporaries), the parent knows
    // whom to forward to.
    sigset_t hold, previousMask;
    sigemptyset(&hold);
    for (int sig : kForwarded) sigaddset(&hold, sig);
    ::sigprocmask(SIG_BLOCK, &hold, &previousMask);
    struct sigaction previous[3];
    struct sigaction forward {};
    forward.sa_handler = forwardToChild;
    sigemptyset(&forward.sa_mask);
    for (int i = 0; i < 3; ++i) {
        ::sigaction(kForwarded[i], nullptr, &previous[i]);
        if (previous[i].sa_handler != SIG_IGN) ::sigaction(kForwarded[i], &forward, nullptr);  // nohup stays nohup
    }
    // waitpid needs SIGCHLD at its default (a caller may have set it to
    // SIG_IGN, and then children are reaped before the wait).
    struct sigaction previousChld {};
    struct sigaction defaultChld {};
    defaultChld.sa_handler = SIG_DFL;
    sigemptyset(&defaultChld.sa_mask);
    ::sigaction(SIGCHLD, &defaultChld, &previousChld);
    gChild = 0;
    gForwarded = 0;
    auto restore = [&] {
        for (int i = 0; i < 3; ++i) ::sigaction(kForwarded[i], &previous[i], nullptr);
        ::sigaction(SIGCHLD, &previousChld, nullptr);
        ::sigprocmask(SIG_SETMASK, &previousMask, nullptr);
    };
    slot->stage[0] = '\0';
    slot->file[0] = '\0';
    const pid_t parent = ::getpid();
    const pid_t child = ::fork();
    if (child < 0) {
        const Error e = cannotStart("fork");
        restore();
        ::close(fds[0]);
        ::close(fds[1]);
        throw e;
    }
    if (child == 0) {
        restore();
        ::close(fds[0]);
        recordStagesIn(slot);
        childMain(work, fds[1], parent);
    }
    gChild = child;
    ::sigprocmask(SIG_SETMASK, &previousMask, nullptr);
    ::close(fds[1]);
    std::string text;
    char buf[4096];
    for (;;) {
        const ssize_t n = ::read(fds[0], buf, sizeof buf);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;
        text.append(buf, static_cast<std::size_t>(n));
    }
    ::close(fds[0]);
    int status = 0;
    pid_t waited;
    while ((waited = ::waitpid(child, &status, 0)) < 0 && errno == EINTR) {
    }
    gChild = 0;
    for (int i = 0; i < 3; ++i) ::sigaction(kForwarded[i], &previous[i], nullptr);
    ::sigaction(SIGCHLD, &previousChld, nullptr);
    // A result that arrived whole stands, whatever happened to the child
    // after sending it.
    nlohmann::json msg = nlohmann::json::parse(text, nullptr, false);
    const bool complete = !msg.is_discarded() && msg.is_object() && (msg.contains("result") || msg.contains("error"));
    if (const int sig = gForwarded; sig != 0) {
        if (!complete) removeLeftovers(files, existed, child);
        std::raise(sig);  // the handler the parent had (by default: remove temporaries, end by the signal)
    }
    if (!complete) {
        removeLeftovers(files, existed, child);
        // Killed for writing to a closed stdout (isohex ... | head): end the
        // same way, as the one process did.
        if (waited == child && WIFSIGNALED(status) && WTERMSIG(status) == SIGPIPE) std::raise(SIGPIPE);
        throw Error(describeEnd(input, status, std::string(slot->stage), std::string(slot->file)));
    }
    if (msg.contains("result")) return msg["result"];
    rethrowChildError(msg, input, *slot);
}

std::string memoryLimitText() {
    rlimit r{};
    if (::getrlimit(RLIMIT_AS, &r) != 0 || r.rlim_cur == RLIM_INFINITY) return {};
    return " (under an address-space limit of " + std::to_string(r.rlim_cur >> 20) + " MB, ulimit -v)";
}

nlohmann::json bytesOf(const std::string& s) { return std::vector<std::uint8_t>(s.begin(), s.end()); }

std::string textOf(const nlohmann::json& j) {
    if (!j.is_array()) return {};
    const auto b = j.get<std::vector<std::uint8_t>>();
    return std::string(b.begin(), b.end());
}

}  // namespace isohex::cli

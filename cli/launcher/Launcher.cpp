// The isohex command: a small launcher in front of the program (isohex-run,
// in the same folder). It answers `isohex --version` itself, from the header
// versions, without loading any library of the pipeline; every other command
// line goes to isohex-run through exec, with glibc's huge-page tunable set, so
// each run loads the program's libraries once.
//
// Why the tunable is set here: the mesh arrays run to hundreds of megabytes,
// and on 4 KiB pages a large part of a run is spent in page faults (hundreds
// of thousands for a 2 M-hex mesh). glibc's malloc asks the kernel for
// transparent huge pages when glibc.malloc.hugetlb is 1, but reads its
// tunables only at start-up. Not set when the kernel has transparent huge
// pages off, when the user already set it, or with ISOHEX_HUGEPAGES=0.
//
// Under an address-space limit (ulimit -v, or a scheduler's virtual-memory
// request such as SGE's h_vmem) isohex-run can fail before its main runs:
// libraries start threads while they are loaded (log4cplus, which OpenVDB
// links, starts four, each reserving a stack of ulimit -s), and when the
// limit leaves no room for them the C++ runtime aborts with "terminate
// called ...", which no code of isohex's can catch. So under a finite limit
// the launcher first runs isohex-run with --start-probe (StartProbe.hpp), its
// output discarded, and says why in one line if that does not return 0. The
// check costs one start of isohex-run (about 90 ms), paid only under a limit
// below 512 MB plus eight thread stacks; above that the launcher execs at once.
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <string_view>
#include <optional>
#include <system_error>

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "../StartProbe.hpp"
#include "../Versions.hpp"

namespace {

void addHugePageTunable() {
    const char* opt = std::getenv("ISOHEX_HUGEPAGES");
    if (opt && std::string(opt) == "0") return;
    const char* cur = std::getenv("GLIBC_TUNABLES");
    std::string tunables = cur ? cur : "";
    if (tunables.find("glibc.malloc.hugetlb") != std::string::npos) return;
    std::ifstream thp("/sys/kernel/mm/transparent_hugepage/enabled");
    std::string mode;
    std::getline(thp, mode);
    if (mode.find("[always]") == std::string::npos && mode.find("[madvise]") == std::string::npos) return;
    tunables += (tunables.empty() ? "" : ":") + std::string("glibc.malloc.hugetlb=1");
    setenv("GLIBC_TUNABLES", tunables.c_str(), 1);
}

std::string megabytes(rlim_t bytes) { return std::to_string(bytes >> 20) + " MB"; }

// Runs `program --start-probe` with its output discarded; returns the line to
// print when it did not start, nothing when it did or when there is no limit.
std::optional<std::string> startFailure(const std::filesystem::path& program) {
    rlimit as{}, stack{};
    if (::getrlimit(RLIMIT_AS, &as) != 0 || as.rlim_cur == RLIM_INFINITY) return std::nullopt;
    const bool stackLimited = ::getrlimit(RLIMIT_STACK, &stack) == 0 && stack.rlim_cur != RLIM_INFINITY;
    // glibc gives threads 32 MB stacks when ulimit -s is unlimited.
    const double stackBytes = stackLimited ? double(stack.rlim_cur) : 32.0 * (1 << 20);
    // Loading takes about 70 MB and four stacks (bench/RESULTS.md): far above
    // that, starting cannot fail and the probe's start-up is not paid.
    if (double(as.rlim_cur) > 512.0 * (1 << 20) + 8 * stackBytes) return std::nullopt;
    if (::access(program.c_str(), X_OK) != 0) return std::nullopt;  // the exec below says what is wrong
    const pid_t child = ::fork();
    if (child < 0) return std::nullopt;  // no probe: the run itself will tell
    if (child == 0) {
        const int null = ::open("/dev/null", O_WRONLY);
        if (null >= 0) {
            ::dup2(null, STDOUT_FILENO);
            ::dup2(null, STDERR_FILENO);
        }
        std::string flag(isohex::cli::kStartProbeFlag);
        char* args[] = {const_cast<char*>(program.c_str()), flag.data(), nullptr};
        ::execv(program.c_str(), args);
        ::_exit(127);
    }
    int status = 0;
    while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
    }
    // Any other end (an abort, or the loader's exit 127 when a library
    // cannot be mapped) is the limit's doing: with no limit it starts.
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return std::nullopt;
    const std::string stackText = stackLimited ? megabytes(stack.rlim_cur) : "unlimited";
    return "cannot start under the address-space limit of " + megabytes(as.rlim_cur) +
           " (ulimit -v): loading its libraries and their threads (each reserving a stack of ulimit -s, now " +
           stackText +
           ") takes more address space than that, before any input is read; raise the limit (ulimit -v, or "
           "the job's virtual-memory request such as SGE's h_vmem) by a few hundred MB";
}

}  // namespace

int main(int argc, char** argv) {
    if (argc == 2 && std::string_view(argv[1]) == "--version") {
        std::cout << isohex::cli::versionText() << "\n";
        return 0;
    }
    std::error_code ec;
    const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
    const std::filesystem::path program = self.parent_path() / "isohex-run";
    addHugePageTunable();
    if (!ec) {
        if (const auto failure = startFailure(program)) {
            std::cerr << "isohex: error: " << *failure << "\n";
            return 1;
        }
        execv(program.c_str(), argv);
    }
    std::cerr << "isohex: error: cannot run the isohex program " << program.string() << ": "
              << (ec ? ec.message() : std::strerror(errno))
              << "; it is installed beside the isohex command (bin/isohex-run, build/cli/isohex-run): "
                 "reinstall isohex or build the target isohex\n";
    return 1;
}

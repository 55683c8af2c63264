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
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <string_view>
#include <system_error>

#include <unistd.h>

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
    if (!ec) execv(program.c_str(), argv);
    std::cerr << "isohex: error: cannot run the isohex program " << program.string() << ": "
              << (ec ? ec.message() : std::strerror(errno))
              << "; it is installed beside the isohex command (bin/isohex-run, build/cli/isohex-run): "
                 "reinstall isohex or build the target isohex\n";
    return 1;
}

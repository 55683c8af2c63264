// isohex: volumetric scans to all-hex finite-element meshes.
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>

#include <unistd.h>

#include <CLI/CLI.hpp>

#include "Commands.hpp"
#include "ErrorText.hpp"
#include "Isolate.hpp"
#include "isohex/core/AtomicFile.hpp"
#include "Versions.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::cli {
int& pendingExitCode() {
    static int code = kExitOk;
    return code;
}
}  // namespace isohex::cli

namespace {

// The mesh arrays run to hundreds of megabytes, and on 4 KiB pages a large part
// of the run is spent in page faults (hundreds of thousands for a 2 M-hex mesh).
// glibc's malloc asks the kernel for transparent huge pages when its tunable
// glibc.malloc.hugetlb is 1, but it reads tunables only at start-up, so isohex
// re-executes itself once with the tunable added to GLIBC_TUNABLES. Skipped when
// the kernel has transparent huge pages off, when the user already set the
// tunable, or with ISOHEX_HUGEPAGES=0; if the exec fails the run just goes on.
void restartWithHugePages(char** argv) {
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
    if (setenv("GLIBC_TUNABLES", tunables.c_str(), 1) != 0) return;
    execv("/proc/self/exe", argv);
    // Only reached when the exec failed: leave the environment as it was.
    if (cur) setenv("GLIBC_TUNABLES", cur, 1); else unsetenv("GLIBC_TUNABLES");
}

// A first word that is not an option and not a command: CLI11 would say "A
// subcommand is required", which reads as if none had been given.
bool refuseUnknownCommand(const CLI::App& app, int argc, char** argv) {
    if (argc < 2 || argv[1][0] == '-') return false;
    const std::string word = argv[1];
    std::string names;
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
        if (sub->check_name(word)) return false;
        names += (names.empty() ? "" : ", ") + sub->get_name();
    }
    std::cerr << "isohex: error: unknown command '" << isohex::boundedMessage(word, 200) << "'; the commands are "
              << names << " (isohex --help describes them)\n";
    return true;
}

}  // namespace

int main(int argc, char** argv) {
    using namespace isohex::cli;
    restartWithHugePages(argv);
    isohex::io::removeTemporariesOnSignal();  // an interrupted write leaves no hidden temporary
    CLI::App app{"isohex: turns volumetric scans into all-hexahedral finite-element meshes\n"
                 "whose every element is convex with positive volume, and reports their quality."};
    app.set_version_flag("--version", versionText());
    app.require_subcommand(1);
    app.fallthrough();
    addQualityCommand(app);
    addConvertCommand(app);
    addMeshCommand(app);
    addCompareCommand(app);
    addSmoothCommand(app);
    addBatchCommand(app);
    addInsertSheetCommand(app);
    if (refuseUnknownCommand(app, argc, argv)) return kExitUsage;
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        app.exit(e);
        return kExitUsage;
    } catch (const isohex::Error& e) {
        std::cerr << "isohex: error: " << isohex::boundedMessage(userMessage(e, SettingNames::Flags), 65536) << "\n";
        return kExitError;
    } catch (const std::bad_alloc&) {
        std::cerr << "isohex: error: out of memory" << memoryLimitText()
                  << "; try a coarser --size, raise the limit or use a machine with more memory\n";
        return kExitError;
    } catch (const std::exception& e) {
        std::cerr << "isohex: internal error: " << isohex::boundedMessage(e.what())
                  << "\n(please report this with the command line that caused it)\n";
        return kExitError;
    }
    return pendingExitCode();
}

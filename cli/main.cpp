// isohex: volumetric scans to all-hex finite-element meshes. This is the
// program isohex-run, which the isohex launcher (launcher/Launcher.cpp) runs.
#include <cstdio>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>

#include "Commands.hpp"
#include "ErrorText.hpp"
#include "Isolate.hpp"
#include "StartProbe.hpp"
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
    if (argc == 2 && argv[1] == kStartProbeFlag) return kExitOk;  // the launcher's start-up check
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
    addEstimateCommand(app);
    addMergeCommand(app);
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

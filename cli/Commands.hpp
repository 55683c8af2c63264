#pragma once
// Each subcommand registers itself on the CLI11 app; its callback runs the
// work and throws isohex::Error on failure. main() prints errors and picks
// exit codes (libraries never do).
#include <CLI/CLI.hpp>

namespace isohex::cli {

// Exit codes shared by all commands.
inline constexpr int kExitOk = 0;
inline constexpr int kExitError = 1;        // bad input, unreadable file, failed job
inline constexpr int kExitUsage = 2;        // bad command line
inline constexpr int kExitInvalidMesh = 3;  // --strict and the mesh failed a check
// mesh, batch, insert-sheet: a mesh stayed below --min-quality (written only
// with --allow-below); the places are named on stderr and in the report
inline constexpr int kExitBelowQuality = 4;

// Set by a command whose work succeeded but whose verdict should fail the process.
int& pendingExitCode();

void addQualityCommand(CLI::App& app);
void addConvertCommand(CLI::App& app);
void addMeshCommand(CLI::App& app);
void addSmoothCommand(CLI::App& app);
void addCompareCommand(CLI::App& app);
void addBatchCommand(CLI::App& app);
void addInsertSheetCommand(CLI::App& app);
void addEstimateCommand(CLI::App& app);
void addMergeCommand(CLI::App& app);

}  // namespace isohex::cli

#pragma once
// The mesh options of `mesh`, `compare` and `batch` (everything that decides
// the mesh), as one table: each row has the option's name (the flag --name
// and the manifest column name_with_underscores both derive from it), its
// help, how a value is set into the settings and the check of a single
// value. The flags of every command and the columns of a batch manifest are
// made from the rows, and checkSettings() checks the options together, for
// the command line and for every manifest row alike.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "OptionText.hpp"
#include "RunOptions.hpp"
#include "isohex/core/SettingError.hpp"
#include "isohex/pipeline/MeshSettings.hpp"

namespace isohex::cli {

// What a command line (or a manifest row) says about one mesh.
struct MeshArgs {
    pipeline::MeshSettings settings;
    std::string labelList;  // "3,7": parsed into settings.select.labels by checkSettings
    bool labels = false;    // read as label map, all labels
    std::vector<double> sliceSpacing;
    std::optional<double> minSize;  // --min-size: --size under its adaptive name, set by checkSettings
    RunArgs run;
};

// One mesh option.
struct MeshOption {
    std::string name;        // "boundary-layers": flag --boundary-layers, column boundary_layers
    const char* group;       // its section in --help
    const char* help;        // the flag's help
    const char* columnHelp;  // the column's line in `batch --help`; nullptr: a flag only, no column
    // The setting library errors name for this option (isohex::SettingError), if any.
    std::optional<Setting> setting;
    // The options the flag cannot be given with (CLI11 refuses the pair).
    std::vector<std::string> excludes;
    // Declares the flag on a command, writing into the arguments.
    std::function<CLI::Option*(CLI::App&, MeshArgs&)> addFlag;
    // Sets the value of a manifest field; throws FieldError on a bad value.
    std::function<void(const Field&, MeshArgs&)> setColumn;

    std::string flag() const { return "--" + name; }
    std::string column() const;
};

// Every mesh option, in the order of --help.
const std::vector<MeshOption>& meshOptions();

// Declares every mesh option as a flag of `cmd`; with `only`, just the
// options of those names (insert-sheet takes the quality rows alone).
void addMeshOptions(CLI::App* cmd, MeshArgs& a, const std::vector<std::string>& only = {});

// The option whose column is `column` (as MeshOption::column() writes it);
// nullptr if there is none.
const MeshOption* findColumn(const std::string& column);

// The one check of the options together, run for the command line and for
// every manifest row: turns the label list into labels and refuses
// combinations that contradict each other or have no effect. Throws
// isohex::Error naming the flags.
void checkSettings(MeshArgs& a);

}  // namespace isohex::cli

#pragma once
// Command-line options shared by `mesh`, `compare` and `batch`.
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "isohex/pipeline/MeshSettings.hpp"
#include "Progress.hpp"

namespace isohex::cli {

struct MeshArgs {
    pipeline::MeshSettings settings;
    std::string insideMode = "above";
    std::string labelList;          // "3,7"
    bool labels = false;            // read as label map, all labels
    std::vector<double> sliceSpacing;
    std::string interpolation = "trilinear";
    int threads = 0;
    bool quiet = false;
    bool logJson = false;
    bool force = false;
    // turns the parsed strings into settings; throws isohex::Error on bad values
    void finish();
    ProgressSink::Mode progressMode() const {
        return logJson ? ProgressSink::Mode::Json : quiet ? ProgressSink::Mode::Quiet : ProgressSink::Mode::Auto;
    }
};

// Selection, grid and method options (everything that decides the mesh).
void addMeshOptions(CLI::App* cmd, MeshArgs& a);
// --threads, --quiet, --log-json, --force
void addRunOptions(CLI::App* cmd, MeshArgs& a);

}  // namespace isohex::cli

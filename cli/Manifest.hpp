#pragma once
// A batch manifest: a CSV file (a header row naming the columns, then one
// job per row) or a JSON-lines file (one object per line with the same
// keys), read into jobs. A manifest names, per job, an input scan, its output
// mesh file(s) and any mesh options that differ from the command line's; its
// option columns are the mesh options' (cli/MeshOptions.hpp).
//
// The whole manifest is read and checked before the first job runs, so a
// typo in row 900 does not surface after hours of meshing; every such error
// names the manifest file and line. A missing or unreadable scan is not a
// manifest error: that job fails and the others run.
#include <string>
#include <vector>

#include "Jobs.hpp"

namespace isohex::cli {

// The jobs of `file` (.csv, .jsonl or .ndjson), each starting from
// `defaults` (the command line's options). Paths are relative to the
// manifest's folder. Throws isohex::Error naming file and line.
std::vector<Job> readManifest(const std::string& file, const MeshArgs& defaults);

// One line per column: its name and what it takes.
std::string manifestColumnsHelp();

}  // namespace isohex::cli

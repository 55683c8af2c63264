#pragma once
// Shared pieces of the reports commands print or write.
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "isohex/core/Quality.hpp"
#include "isohex/core/Validate.hpp"

namespace isohex::cli {

double peakMemoryMb();
// Whether malloc was told to use transparent huge pages (main.cpp restarts
// isohex with glibc.malloc.hugetlb=1 unless ISOHEX_HUGEPAGES=0).
bool hugePagesRequested();
// Human-readable quality and validity summary for a terminal.
std::string formatQuality(const QualitySummary& q, const ValidityReport& v);
// The defects of v on one readable line: "validity defects: inverted_hex x1
// (description, first at (x, y, z)); ..." (the JSON has every example).
std::string describeDefects(const ValidityReport& v);
// Writes JSON text to `path` atomically (refusing to clobber unless overwrite).
void writeJsonFile(const nlohmann::json& j, const std::string& path, bool overwrite);

}  // namespace isohex::cli

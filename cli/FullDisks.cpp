#include "FullDisks.hpp"

#include <filesystem>
#include <vector>

#include <sys/stat.h>

namespace isohex::cli {

namespace {

// The device of the folder `file` goes to; false when it cannot be read.
bool deviceOf(const std::string& file, unsigned long long& device) {
    std::filesystem::path folder = std::filesystem::path(file).parent_path();
    if (folder.empty()) folder = ".";
    struct stat st {};
    if (::stat(folder.c_str(), &st) != 0) return false;
    device = static_cast<unsigned long long>(st.st_dev);
    return true;
}

}  // namespace

void FullDisks::add(const std::string& folder, const std::string& input) {
    unsigned long long device = 0;
    if (deviceOf(folder + "/.", device)) full_.emplace(device, Found{folder, input});
}

std::string FullDisks::holdsBack(const Job& job) const {
    std::vector<std::string> files = job.outputs;
    if (!job.report.empty()) files.push_back(job.report);
    if (!job.plot.empty()) files.push_back(job.plot);
    for (const std::string& file : files) {
        unsigned long long device = 0;
        if (!deviceOf(file, device)) continue;
        const auto it = full_.find(device);
        if (it == full_.end()) continue;
        return job.input + ": not run: " + file + " would go to the disk holding '" + it->second.folder +
               "', which filled up in the job of " + it->second.input +
               ". Free some space there and run the batch again (the jobs already done are skipped).";
    }
    return {};
}

}  // namespace isohex::cli

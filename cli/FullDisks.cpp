#include "FullDisks.hpp"

#include <filesystem>
#include <system_error>

#include <sys/stat.h>

namespace isohex::cli {

namespace fs = std::filesystem;

namespace {

fs::path folderOf(const std::string& file) {
    const fs::path folder = fs::path(file).parent_path();
    return folder.empty() ? fs::path(".") : folder;
}

// The device of `folder`; false when it cannot be read.
bool deviceOf(const fs::path& folder, std::uintmax_t& device) {
    struct stat st {};
    if (::stat(folder.c_str(), &st) != 0) return false;
    device = static_cast<std::uintmax_t>(st.st_dev);
    return true;
}

// Bytes free for this user on the disk holding `folder`; false when unknown.
bool freeSpace(const fs::path& folder, std::uintmax_t& bytes) {
    std::error_code ec;
    bytes = fs::space(folder, ec).available;
    return !ec;
}

}  // namespace

void FullDisks::add(const std::string& folder, const std::string& input) {
    std::uintmax_t device = 0, bytes = 0;
    if (deviceOf(folder, device) && freeSpace(folder, bytes)) full_.insert_or_assign(device, Found{folder, input, bytes});
}

std::string FullDisks::holdsBack(const Job& job) const {
    for (const std::string& file : filesOf(job)) {
        std::uintmax_t device = 0, bytes = 0;
        if (!deviceOf(folderOf(file), device)) continue;
        const auto it = full_.find(device);
        // Space freed since (files deleted by the user or another program):
        // the job may fit now, so it runs.
        if (it == full_.end() || !freeSpace(folderOf(file), bytes) || bytes > it->second.free) continue;
        return job.input + ": not run: " + file + " would go to the disk holding '" + it->second.folder +
               "', which ran out of space in the job of " + it->second.input +
               ". Free some space there and run the batch again (without --force, the jobs already done are "
               "skipped).";
    }
    return {};
}

}  // namespace isohex::cli

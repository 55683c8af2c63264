#pragma once
// The disks a batch has found full, so that the later jobs that write to one
// are not run while it stays full: each would mesh for minutes and then fail
// at its write. Jobs that write to other disks go on.
#include <cstdint>
#include <map>
#include <string>

#include "Jobs.hpp"

namespace isohex::cli {

class FullDisks {
public:
    // The disk holding `folder` ran out of space in the job of `input`
    // (called after that job's partial files are gone).
    void add(const std::string& folder, const std::string& input);
    // Why `job` is not run: a file of it goes to a disk found full that has
    // no more space than it had after that failure ("" otherwise).
    std::string holdsBack(const Job& job) const;

private:
    struct Found {
        std::string folder;       // where the failed write went
        std::string input;        // the job that found the disk full
        std::uintmax_t free = 0;  // bytes free after that job's files were removed
    };
    std::map<std::uintmax_t, Found> full_;  // by device (stat's st_dev)
};

}  // namespace isohex::cli

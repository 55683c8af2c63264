#pragma once
// The disks a batch has found full, so that the jobs after the one that
// filled a disk and write to it are not run: each would mesh for minutes and
// then fail at its write. Jobs that write to other disks go on.
#include <map>
#include <string>
#include <utility>

#include "Jobs.hpp"

namespace isohex::cli {

class FullDisks {
public:
    // The disk holding `folder` filled up in the job of `input`.
    void add(const std::string& folder, const std::string& input);
    // Why `job` is not run ("" when none of its files goes to a full disk).
    std::string holdsBack(const Job& job) const;

private:
    struct Found {
        std::string folder;  // where the failed write went
        std::string input;   // the job that found the disk full
    };
    std::map<unsigned long long, Found> full_;  // by device (stat's st_dev)
};

}  // namespace isohex::cli

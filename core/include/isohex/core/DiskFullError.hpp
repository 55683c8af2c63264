#pragma once
// The error of a write that failed while the disk it went to was full.
#include <string>
#include <utility>

#include "isohex/core/Error.hpp"

namespace isohex::io {

// Its message says the disk is full and what to do; folder() is where the
// file was going, so that a batch can hold back the later jobs that write
// there (cli/FullDisks.hpp).
class DiskFullError : public Error {
public:
    DiskFullError(const std::string& message, std::string folder) : Error(message), folder_(std::move(folder)) {}
    const std::string& folder() const { return folder_; }

private:
    std::string folder_;
};

}  // namespace isohex::io

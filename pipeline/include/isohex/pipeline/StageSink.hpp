#pragma once
// Where the stages report to: stage begin and end (with its seconds),
// progress fractions, notes and the files being read. The command line draws
// it (cli/Progress.hpp); tests pass a quiet one.
#include <string>
#include <string_view>

namespace isohex::pipeline {

class StageSink {
public:
    virtual ~StageSink() = default;
    virtual void begin(std::string_view stage) = 0;
    virtual void progress(double fraction) = 0;
    virtual void end(std::string_view stage, double seconds) = 0;
    virtual void note(std::string_view level, const std::string& text) = 0;  // "info" or "warning"
    // A file a library is about to open while loading (a DICOM folder's
    // files, one by one), so a crash can be put down to it.
    virtual void reading(const std::string& /*file*/) {}
};

}  // namespace isohex::pipeline

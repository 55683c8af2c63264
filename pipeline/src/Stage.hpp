#pragma once
// A stage timed on a Stopwatch and reported to the sink (internal to pipeline/).
#include <string>
#include <utility>

#include "isohex/core/Stopwatch.hpp"
#include "isohex/pipeline/StageSink.hpp"

namespace isohex::pipeline {

class Stage {
public:
    Stage(StageSink& sink, std::string name) : sink_(sink), name_(std::move(name)) { sink_.begin(name_); }
    // Reports the stage done with its seconds. A stage left by an exception
    // is not reported as done; the error says why.
    double finish() {
        const double s = clock_.seconds();
        sink_.end(name_, s);
        return s;
    }

private:
    StageSink& sink_;
    std::string name_;
    Stopwatch clock_;
};

// Runs fn() as the stage `name` and returns its result.
template <class Fn>
auto timedStage(StageSink& sink, const char* name, Fn fn) {
    Stage st(sink, name);
    auto r = fn();
    st.finish();
    return r;
}

}  // namespace isohex::pipeline

#pragma once
// Numbers in messages, as short as a stream writes them (internal to pipeline/).
#include <sstream>
#include <string>

namespace isohex::pipeline {

inline std::string shortNumber(double v) {
    std::ostringstream o;
    o << v;
    return o.str();
}

}  // namespace isohex::pipeline

#pragma once
// The one exception type the libraries throw. Its message is meant for a user:
// which file or value, what is wrong, and what to do about it.
#include <stdexcept>
#include <string>

namespace isohex {

class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

}  // namespace isohex

#pragma once
// The one exception type the libraries throw. Its message is meant for a user:
// which file or value, what is wrong, and what to do about it.
#include <stdexcept>
#include <string>
#include <string_view>

namespace isohex {

class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// A message for printing, at most about 2 kB: a library's message can quote
// the bad input at length (OpenVDB quoted 1.9 GB of a damaged .vdb file,
// Assimp a whole STL file), so the middle of a longer one is left out.
inline std::string boundedMessage(std::string_view m) {
    constexpr std::size_t kHead = 1500, kTail = 300;
    if (m.size() <= kHead + kTail + 100) return std::string(m);
    return std::string(m.substr(0, kHead)) + " [... " + std::to_string(m.size() - kHead - kTail) +
           " characters left out ...] " + std::string(m.substr(m.size() - kTail));
}

}  // namespace isohex

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

// A message for printing, at most about `limit` bytes: a library's message
// can quote the bad input at length (OpenVDB quoted 1.9 GB of a damaged .vdb
// file, Assimp a whole STL file), so the middle of a longer one is left out.
// The cuts move off UTF-8 continuation bytes, so no character is split (the
// JSON log refuses invalid UTF-8). Library text is bounded where it is put
// into a message (2 kB); whole messages only where printed (64 kB), so that
// isohex's own long lists (a DICOM folder's series) stay whole.
inline std::string boundedMessage(std::string_view m, std::size_t limit = 2000) {
    const std::size_t tail = limit / 6, head = limit - tail;
    if (m.size() <= limit + 100) return std::string(m);
    auto continuation = [&](std::size_t i) { return (static_cast<unsigned char>(m[i]) & 0xC0) == 0x80; };
    std::size_t a = head, b = m.size() - tail;
    while (a > 0 && continuation(a)) --a;
    while (b < m.size() && continuation(b)) ++b;
    return std::string(m.substr(0, a)) + " [... " + std::to_string(b - a) + " characters left out ...] " +
           std::string(m.substr(b));
}

}  // namespace isohex

// The imaging tests' file and message helpers (see TestSupport.hpp).
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "TestSupport.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::imaging::test {

std::string expectError(const std::function<void()>& f, const std::vector<std::string>& pieces) {
    try {
        f();
    } catch (const isohex::Error& e) {
        const std::string msg = e.what();
        for (const auto& p : pieces) EXPECT_NE(msg.find(p), std::string::npos) << "'" << p << "' not in: " << msg;
        return msg;
    } catch (const std::exception& e) {
        ADD_FAILURE() << "threw a non-isohex exception: " << e.what();
        return {};
    }
    ADD_FAILURE() << "no exception";
    return {};
}

void writeBytes(const fs::path& p, const std::string& bytes) { std::ofstream(p, std::ios::binary) << bytes; }

std::string readAll(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace isohex::imaging::test

// boundedMessage: long library text is cut in the middle, never inside a
// UTF-8 character; short text is left as it is.
#include <gtest/gtest.h>

#include <string>

#include "isohex/core/Error.hpp"

namespace {

bool validUtf8(const std::string& s) {
    for (std::size_t i = 0; i < s.size();) {
        const auto c = static_cast<unsigned char>(s[i]);
        const std::size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
        if (n == 0 || i + n > s.size()) return false;
        for (std::size_t k = 1; k < n; ++k)
            if ((static_cast<unsigned char>(s[i + k]) & 0xC0) != 0x80) return false;
        i += n;
    }
    return true;
}

}  // namespace

TEST(BoundedMessage, ShortTextIsUnchanged) {
    const std::string m = "scan.nii: voxel spacing along axis 0 is 0";
    EXPECT_EQ(isohex::boundedMessage(m), m);
}

TEST(BoundedMessage, LongTextKeepsItsEndsAndStaysValidUtf8) {
    // "é" is two bytes: every cut point of a run of them falls mid-character
    // for one of the two alignments
    for (const std::string lead : {"", "x"}) {
        std::string m = lead + "start ";
        for (int i = 0; i < 100000; ++i) m += "\xC3\xA9";
        m += " end";
        const std::string b = isohex::boundedMessage(m);
        EXPECT_LT(b.size(), 2200u);
        EXPECT_EQ(b.rfind(lead + "start ", 0), 0u);
        EXPECT_EQ(b.substr(b.size() - 4), " end");
        EXPECT_NE(b.find("characters left out"), std::string::npos);
        EXPECT_TRUE(validUtf8(b));
        EXPECT_LT(isohex::boundedMessage(m, 65536).size(), 66000u);
        EXPECT_TRUE(validUtf8(isohex::boundedMessage(m, 65536)));
    }
}

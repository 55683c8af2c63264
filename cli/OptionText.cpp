#include "OptionText.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>

namespace isohex::cli {

std::string trim(const std::string& s) {
    const auto b = s.find_first_not_of(" \t\r\n");
    if (b == std::string::npos) return {};
    return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

std::vector<std::string> Field::items(const std::string& separators) const {
    if (isList) return list;
    std::vector<std::string> out;
    std::string cur;
    for (char c : text) {
        if (separators.find(c) != std::string::npos) {
            if (!trim(cur).empty()) out.push_back(trim(cur));
            cur.clear();
        } else {
            cur += c;
        }
    }
    if (!trim(cur).empty()) out.push_back(trim(cur));
    return out;
}

const std::string& Field::scalar() const {
    if (isList) throw FieldError{"expected one value, got a list"};
    return text;
}

double toNumber(const std::string& s) {
    const std::string t = trim(s);
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(t.c_str(), &end);
    if (t.empty() || end != t.c_str() + t.size() || errno == ERANGE || !std::isfinite(v))
        throw FieldError{"expected a number, got '" + s + "'"};
    return v;
}

long long toInteger(const std::string& s) {
    const std::string t = trim(s);
    char* end = nullptr;
    errno = 0;
    const long long v = std::strtoll(t.c_str(), &end, 10);
    if (t.empty() || end != t.c_str() + t.size() || errno == ERANGE)
        throw FieldError{"expected a whole number, got '" + s + "'"};
    return v;
}

bool toBool(const std::string& s) {
    std::string t = trim(s);
    std::transform(t.begin(), t.end(), t.begin(), [](unsigned char c) { return std::tolower(c); });
    if (t == "1" || t == "true" || t == "yes" || t == "on" || t == "y") return true;
    if (t == "0" || t == "false" || t == "no" || t == "off" || t == "n") return false;
    throw FieldError{"expected true or false (also yes/no, 1/0), got '" + s + "'"};
}

std::string choiceList(const std::vector<std::string>& names) {
    std::string all;
    for (const auto& n : names) all += (all.empty() ? "" : " or ") + n;
    return all;
}

void throwBadChoice(const std::string& s, const std::vector<std::string>& names) {
    throw FieldError{"expected " + choiceList(names) + ", got '" + s + "'"};
}

}  // namespace isohex::cli

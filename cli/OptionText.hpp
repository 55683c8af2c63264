#pragma once
// Option values given as text: a batch manifest's fields (a CSV cell, or a
// JSON scalar or array), parsed and checked the way the command line's flags
// are. A bad value throws FieldError; the caller adds file, line and column.
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

namespace isohex::cli {

// A bad value in one field; the caller adds where it is.
struct FieldError {
    std::string message;
};

// One field of a manifest row: a text (CSV, or a JSON scalar) or a list (a
// JSON array). An empty text means "not given: use the default".
struct Field {
    std::string text;
    std::vector<std::string> list;
    bool isList = false;

    bool empty() const { return isList ? list.empty() : text.empty(); }
    // The items of a list-valued column: a JSON array, or a text split at any
    // of `separators` (empty items dropped).
    std::vector<std::string> items(const std::string& separators) const;
    // The text of a one-value column; a list is an error.
    const std::string& scalar() const;
};

// `s` without leading and trailing blanks.
std::string trim(const std::string& s);

// The value of a text, or FieldError saying what was expected.
double toNumber(const std::string& s);
long long toInteger(const std::string& s);
bool toBool(const std::string& s);  // true/false, yes/no, on/off, y/n, 1/0
// The value named by `s` among `choices` (name, value); FieldError lists the names.
template <class T>
T toChoice(const std::string& s, const std::vector<std::pair<std::string, T>>& choices);

// "a or b or c"
std::string choiceList(const std::vector<std::string>& names);
[[noreturn]] void throwBadChoice(const std::string& s, const std::vector<std::string>& names);

template <class T>
T toChoice(const std::string& s, const std::vector<std::pair<std::string, T>>& choices) {
    const std::string t = trim(s);
    std::vector<std::string> names;
    for (const auto& [name, value] : choices) {
        if (t == name) return value;
        names.push_back(name);
    }
    throwBadChoice(s, names);
}

}  // namespace isohex::cli

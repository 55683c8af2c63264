// NRRD checks around ITK's (teem's) reader (see FormatChecks.hpp).
#include <cctype>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <vector>

#include "DataFilePlace.hpp"
#include "FormatChecks.hpp"

namespace isohex::imaging::detail {
namespace {

std::string trimmed(std::string t) {
    while (!t.empty() && std::isspace(static_cast<unsigned char>(t.back()))) t.pop_back();
    std::size_t i = 0;
    while (i < t.size() && std::isspace(static_cast<unsigned char>(t[i]))) ++i;
    return t.substr(i);
}

// A NRRD header's fields ("field: value" lines up to the first blank line;
// comments and "key:=value" pairs left out), the names listed after
// "data file: LIST", and the field names in teem's two spellings.
struct NrrdHeader {
    std::vector<std::pair<std::string, std::string>> fields;
    std::vector<std::string> listed;

    explicit NrrdHeader(const std::string& file) {
        std::ifstream in(file, std::ios::binary);
        std::string line;
        if (!std::getline(in, line) || line.rfind("NRRD", 0) != 0) return;
        bool list = false;
        for (int n = 0; n < 10000 && std::getline(in, line); ++n) {
            if (!line.empty() && line.back() == '\r') line.pop_back();
            if (list) {
                if (!trimmed(line).empty()) listed.push_back(trimmed(line));
                continue;
            }
            if (line.empty()) break;  // the end of the header: attached data follows
            if (line[0] == '#' || line.find(":=") != std::string::npos) continue;
            const auto colon = line.find(':');
            if (colon == std::string::npos) continue;
            std::string key;
            for (char c : line.substr(0, colon))
                if (c != ' ') key += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
            fields.emplace_back(key, trimmed(line.substr(colon + 1)));
            // LIST: the file names follow, one a line, to the end of the header file
            list = key == "datafile" && fields.back().second.rfind("LIST", 0) == 0;
        }
    }
    const std::string* get(const char* key) const {
        for (const auto& [k, v] : fields)
            if (k == key) return &v;
        return nullptr;
    }
};

// The data files of "data file: <format> <min> <max> <step> [<subdim>]", or
// nothing if the value is one file's name.
std::vector<std::string> patternFiles(const std::string& file, const std::string& value) {
    std::istringstream in(value);
    std::string format;
    long long first = 0, last = 0, step = 0;
    if (!(in >> format >> first >> last >> step) || format.find('%') == std::string::npos) return {};
    if (!isOneIntegerPattern(format))
        throw Error(file + ": the NRRD header's data file pattern '" + format +
                    "' must hold one integer field such as %03d; fix the header.");
    if (step == 0 || (last - first) / step < 0 || (last - first) / step > 100000)
        throw Error(file + ": the NRRD header's data file pattern '" + value +
                    "' names no files or too many; write it as 'format min max step' and retry.");
    std::vector<std::string> names;
    for (long long i = first; step > 0 ? i <= last : i >= last; i += step) {
        char name[4096];
        std::snprintf(name, sizeof name, format.c_str(), static_cast<int>(i));
        names.emplace_back(name);
    }
    return names;
}

}  // namespace

// teem follows "data file" anywhere, reads a byte skip below -1 (only -1,
// "the data ends the file", is defined) as a shift of the data, and a
// negative line skip as none: each was meshed without a word.
void checkNrrdHeader(const std::string& file, bool allowDataOutside) {
    const NrrdHeader h(file);
    for (const char* key : {"byteskip", "lineskip"})
        if (const std::string* value = h.get(key)) {
            long long skip = 0;
            std::istringstream(*value) >> skip;
            const long long lowest = key[0] == 'b' ? -1 : 0;
            if (skip < lowest)
                throw Error(file + ": the NRRD header's " + (key[0] == 'b' ? "byte skip" : "line skip") + " is " +
                            *value + "; it must be " + std::to_string(lowest) +
                            " or more (the bytes or lines before the data). Fix the header and retry.");
        }
    const std::string* dataFile = h.get("datafile");
    if (!dataFile) return;  // the data is attached
    std::vector<std::string> names;
    if (dataFile->rfind("LIST", 0) == 0)
        names = h.listed;
    else if (names = patternFiles(file, *dataFile); names.empty())
        names.push_back(*dataFile);
    for (const auto& name : names) checkDataFilePlace(file, name, allowDataOutside);
}

}  // namespace isohex::imaging::detail

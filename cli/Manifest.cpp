// CSV is parsed by libcsv (Debian's libcsv-dev, RFC 4180: quoted fields,
// doubled quotes, commas and line breaks inside quotes, CRLF), in strict mode
// so that a stray quote is reported instead of guessed at. Debian's only C++
// CSV library, libfccp-dev (fast-cpp-csv-parser, a 2016 snapshot), fixes the
// number and names of columns at compile time and does not accept line
// breaks inside quoted fields, so it does not fit a manifest whose option
// columns are optional. JSON lines are parsed by nlohmann-json.
#include "Manifest.hpp"

#include <csv.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "OptionText.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/MeshIO.hpp"

namespace isohex::cli {

namespace {

namespace fs = std::filesystem;

// Per-job values that are not mesh settings.
struct JobFields {
    std::string input;
    std::vector<std::string> outputs;
    std::string report;
    std::string plot;
};

// The columns of a job's files; every other column is a mesh option's.
struct JobColumn {
    const char* name;
    const char* help;
    void (*set)(const Field&, JobFields&);
};

const JobColumn kJobColumns[] = {
    {"input", "scan to mesh (required)", [](const Field& f, JobFields& j) { j.input = f.scalar(); }},
    {"output", "output mesh file(s), several separated by ';' (required)",
     [](const Field& f, JobFields& j) { j.outputs = f.items(";"); }},
    {"report", "JSON report path", [](const Field& f, JobFields& j) { j.report = f.scalar(); }},
    {"plot", "SVG histogram path", [](const Field& f, JobFields& j) { j.plot = f.scalar(); }},
};

const JobColumn* findJobColumn(const std::string& name) {
    for (const JobColumn& c : kJobColumns)
        if (name == c.name) return &c;
    return nullptr;
}

// Column names are compared after lower-casing and turning '-' into '_'
// (and dropping leading dashes), so "no-pillow" and "--no-pillow" name the
// same column as "no_pillow".
std::string normalizeName(std::string s) {
    s = trim(s);
    while (!s.empty() && s.front() == '-') s.erase(s.begin());
    for (char& c : s) c = c == '-' ? '_' : static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

std::string knownColumns() {
    std::string s;
    for (const JobColumn& c : kJobColumns) s += std::string(s.empty() ? "" : ", ") + c.name;
    for (const MeshOption& o : meshOptions())
        if (o.columnHelp) s += ", " + o.column();
    return s;
}

// One row of the manifest: (column name, field) pairs and where it starts.
struct Row {
    std::size_t line = 0;
    std::vector<std::pair<std::string, Field>> fields;
};

[[noreturn]] void fail(const std::string& file, std::size_t line, const std::string& what) {
    throw Error(file + (line ? ":" + std::to_string(line) : std::string()) + ": " + what);
}

// The column `raw` names (its normalised name), or an error naming the file and line.
std::string columnOf(const std::string& file, std::size_t line, const std::string& raw, const char* kind) {
    const std::string name = normalizeName(raw);
    if (const auto flag = runOptionFlag(name))
        fail(file, line,
             std::string(kind) + " '" + raw + "' is an option of the whole run; give " + *flag + " on the command line");
    if (findJobColumn(name) || cli::findColumn(name)) return name;
    fail(file, line, "unknown " + std::string(kind) + " '" + raw + "' (known: " + knownColumns() + ")");
}

std::string readFile(const std::string& path) {
    std::error_code ec;
    if (fs::is_directory(path, ec)) throw Error(path + ": is a folder; the manifest is a .csv or .jsonl file");
    std::ifstream in(path, std::ios::binary);
    if (!in)
        throw Error(path + ": cannot read the manifest (" +
                    (fs::exists(path, ec) ? "permission denied" : "no such file") + ")");
    std::ostringstream s;
    s << in.rdbuf();
    std::string text = s.str();
    if (text.rfind("\xEF\xBB\xBF", 0) == 0) text.erase(0, 3);  // UTF-8 byte order mark (spreadsheet exports)
    return text;
}

// CSV through libcsv

struct CsvState {
    std::size_t line = 1;            // line being fed to the parser
    std::vector<std::string> cells;  // fields of the record being read
    std::size_t recordLine = 0;      // line of its first field
    std::size_t lastEnd = 0;         // line on which the last record ended (0: none yet)
    std::vector<std::pair<std::size_t, std::vector<std::string>>> records;
};

void csvField(void* data, std::size_t len, void* user) {
    auto* st = static_cast<CsvState*>(user);
    if (st->cells.empty()) st->recordLine = st->line;
    st->cells.emplace_back(data ? static_cast<const char*>(data) : "", data ? len : 0);
}

void csvRecord(int, void* user) {
    auto* st = static_cast<CsvState*>(user);
    const bool blank = std::all_of(st->cells.begin(), st->cells.end(), [](const std::string& c) { return c.empty(); });
    if (!st->cells.empty() && !blank) st->records.emplace_back(st->recordLine, std::move(st->cells));
    st->cells.clear();
    st->lastEnd = st->line;
}

std::vector<Row> readCsv(const std::string& file) {
    const std::string text = readFile(file);
    csv_parser p;
    if (csv_init(&p, CSV_STRICT | CSV_STRICT_FINI) != 0) throw Error("cannot initialise the CSV parser");
    std::unique_ptr<csv_parser, void (*)(csv_parser*)> guard(&p, [](csv_parser* q) { csv_free(q); });
    CsvState st;
    // Fed one line at a time so that errors and records know their line.
    std::size_t pos = 0;
    while (pos < text.size()) {
        std::size_t nl = text.find('\n', pos);
        const std::size_t len = (nl == std::string::npos ? text.size() : nl + 1) - pos;
        if (csv_parse(&p, text.data() + pos, len, csvField, csvRecord, &st) != len)
            fail(file, st.line,
                 "malformed CSV (" + std::string(csv_strerror(csv_error(&p))) +
                     "): a quote inside an unquoted field, or text after a closing quote; "
                     "quote fields that contain commas or quotes and double the quotes inside");
        pos += len;
        if (nl != std::string::npos) ++st.line;
    }
    // The open record's line: that of its first field if one was read, else
    // (the quote opens its first field) the first non-blank line after the
    // last record's end.
    std::size_t openLine = st.recordLine;
    const bool fieldsRead = !st.cells.empty();
    if (csv_fini(&p, csvField, csvRecord, &st) != 0) {
        if (!fieldsRead) {
            std::size_t line = 1, start = 0;
            openLine = st.lastEnd + 1;
            for (; start < text.size() && line <= st.lastEnd; ++line) start = text.find('\n', start) + 1;
            while (start < text.size()) {
                const std::size_t end = std::min(text.find('\n', start), text.size());
                if (text.find_first_not_of(" \t\r", start) < end) break;
                start = end + 1;
                ++openLine;
            }
        }
        fail(file, openLine,
             "malformed CSV (" + std::string(csv_strerror(csv_error(&p))) + "): a quoted field is not closed");
    }
    if (st.records.empty()) fail(file, 0, "empty manifest: expected a header row such as 'input,output,size'");
    const auto& [headerLine, header] = st.records.front();
    std::vector<std::string> cols;
    std::set<std::string> seen;
    for (const auto& h : header) {
        if (trim(h).empty()) fail(file, headerLine, "the header has an empty column name");
        std::string name = columnOf(file, headerLine, h, "column");
        if (!seen.insert(name).second) fail(file, headerLine, "column '" + name + "' appears twice");
        cols.push_back(std::move(name));
    }
    std::vector<Row> rows;
    for (std::size_t r = 1; r < st.records.size(); ++r) {
        const auto& [line, cells] = st.records[r];
        if (cells.size() != cols.size())
            fail(file, line,
                 std::to_string(cells.size()) + " field(s) but the header has " + std::to_string(cols.size()) +
                     " column(s) (quote fields that contain commas)");
        Row row{line, {}};
        for (std::size_t i = 0; i < cells.size(); ++i)
            row.fields.emplace_back(cols[i], Field{cells[i], {}, false});
        rows.push_back(std::move(row));
    }
    return rows;
}

// JSON lines through nlohmann-json

std::string scalarText(const nlohmann::json& v) {
    if (v.is_string()) return v.get<std::string>();
    if (v.is_boolean()) return v.get<bool>() ? "true" : "false";
    if (v.is_number()) return v.dump();
    if (v.is_null()) return {};
    throw FieldError{"expected a value or a list of values, got " + std::string(v.type_name())};
}

std::vector<Row> readJsonLines(const std::string& file) {
    const std::string text = readFile(file);
    std::vector<Row> rows;
    std::istringstream in(text);
    std::string lineText;
    for (std::size_t line = 1; std::getline(in, lineText); ++line) {
        if (trim(lineText).empty()) continue;
        nlohmann::json obj;
        try {
            obj = nlohmann::json::parse(lineText);
        } catch (const nlohmann::json::parse_error& e) {
            std::string what = e.what();
            if (const auto k = what.find("] "); k != std::string::npos) what = what.substr(k + 2);
            fail(file, line, "not valid JSON: " + what);
        }
        if (!obj.is_object())
            fail(file, line,
                 "expected one JSON object per line, e.g. {\"input\": \"a.nii.gz\", \"output\": \"a.vtu\"}");
        Row row{line, {}};
        for (const auto& [key, val] : obj.items()) {
            const std::string name = columnOf(file, line, key, "key");
            Field f;
            try {
                if (val.is_array()) {
                    f.isList = true;
                    for (const auto& item : val) f.list.push_back(scalarText(item));
                } else {
                    f.text = scalarText(val);
                }
            } catch (const FieldError& e) {
                fail(file, line, "key '" + key + "': " + e.message);
            }
            row.fields.emplace_back(name, std::move(f));
        }
        rows.push_back(std::move(row));
    }
    return rows;
}

std::string lowerExtension(const std::string& path) {
    std::string e = fs::path(path).extension().string();
    std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
    return e;
}

// Paths in a manifest are relative to the manifest's folder.
std::string resolve(const fs::path& base, const std::string& p) {
    if (p.empty() || fs::path(p).is_absolute()) return p;
    return (base / p).lexically_normal().string();
}

std::vector<Row> readRows(const std::string& file) {
    const std::string ext = lowerExtension(file);
    if (ext == ".csv") return readCsv(file);
    if (ext == ".jsonl" || ext == ".ndjson") return readJsonLines(file);
    throw Error(file + ": unknown manifest type '" + ext +
                "': name it .csv (a header row, then one job per row) or .jsonl / .ndjson (one JSON object per line)");
}

// One row read into a job: its file columns into `j`, its option columns
// over the command line's options. A job's own choice replaces the command
// line's rather than clashing with it: size replaces level and the other way
// round, iso a label selection, labels/label an iso value.
void applyRow(const std::string& file, const Row& row, Job& job, JobFields& j) {
    std::set<std::string> given;
    bool labelsOff = false;  // labels=false: an intensity image
    for (const auto& [name, field] : row.fields) {
        if (field.empty()) continue;  // not given: the command line's value
        try {
            if (const JobColumn* c = findJobColumn(name)) c->set(field, j);
            else cli::findColumn(name)->setColumn(field, job.args);
        } catch (const FieldError& e) {
            fail(file, row.line, "column '" + name + "': " + e.message);
        }
        given.insert(name);
        if (name == "labels") labelsOff = !job.args.labels;
    }
    const bool sawSize = given.count("size"), sawLevel = given.count("level"), sawIso = given.count("iso");
    const bool labelsOn = given.count("label") || (given.count("labels") && !labelsOff);
    if (sawSize && sawLevel) fail(file, row.line, "give either size or level, not both");
    if (sawSize) job.args.settings.level.reset();
    if (sawLevel) job.args.settings.size.reset();
    if (sawIso && labelsOn) fail(file, row.line, "iso applies to intensity images, labels/label to label maps; give one");
    if (labelsOn && labelsOff) fail(file, row.line, "labels is false but label lists labels");
    if (sawIso || labelsOff) {
        job.args.labels = false;
        job.args.labelList.clear();
    }
    if (labelsOn) job.args.settings.select.iso.reset();
}

// The job's files, relative to the manifest's folder, with known output formats.
void placeFiles(const std::string& file, std::size_t line, const fs::path& base, const JobFields& j, Job& job) {
    job.input = resolve(base, j.input);
    for (const auto& o : j.outputs) {
        job.outputs.push_back(resolve(base, o));
        try {
            io::formatFromPath(job.outputs.back());
        } catch (const Error& e) {
            fail(file, line, e.what());
        }
    }
    job.report = resolve(base, j.report);
    job.plot = resolve(base, j.plot);
}

}  // namespace

std::vector<Job> readManifest(const std::string& file, const MeshArgs& defaults) {
    const std::vector<Row> rows = readRows(file);
    const fs::path base = fs::path(file).parent_path();
    std::vector<Job> jobs;
    std::map<std::string, std::size_t> written;  // output path -> line of the job writing it
    for (const Row& row : rows) {
        Job job;
        job.args = defaults;
        JobFields j;
        applyRow(file, row, job, j);
        if (j.input.empty()) fail(file, row.line, "no input: every job needs an 'input' scan");
        if (j.outputs.empty())
            fail(file, row.line, "no output: every job needs an 'output' mesh file (several separated by ';')");
        try {
            MeshArgs check = job.args;
            checkSettings(check);
        } catch (const Error& e) {
            fail(file, row.line, e.what());
        }
        placeFiles(file, row.line, base, j, job);
        std::vector<std::string> all = job.outputs;
        if (!job.report.empty()) all.push_back(job.report);
        if (!job.plot.empty()) all.push_back(job.plot);
        for (const auto& o : all) {
            const std::string key = fs::absolute(o).lexically_normal().string();
            if (const auto it = written.find(key); it != written.end())
                fail(file, row.line, o + " is also written by the job on line " + std::to_string(it->second));
            written[key] = row.line;
        }
        jobs.push_back(std::move(job));
    }
    return jobs;
}

std::string manifestColumnsHelp() {
    std::string s;
    auto line = [&](const std::string& name, const char* help) {
        s += "  " + name + std::string(18 - std::min<std::size_t>(17, name.size()), ' ') + help + "\n";
    };
    for (const JobColumn& c : kJobColumns) line(c.name, c.help);
    for (const MeshOption& o : meshOptions())
        if (o.columnHelp) line(o.column(), o.columnHelp);
    return s;
}

}  // namespace isohex::cli

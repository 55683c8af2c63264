// isohex batch MANIFEST: mesh every job listed in a CSV or JSON-lines file.
//
// A manifest names, per job, an input scan, its output mesh file(s) and any
// mesh options that differ from the defaults given on the command line. The
// jobs run through runJobs (cli/Jobs.hpp): a failing job does not stop the
// others, up-to-date outputs are skipped (resumable) unless --force, a summary
// table goes to stdout and the exit status is non-zero if any job failed.
//
// The whole manifest is read and checked before the first job runs, so a typo
// in row 900 does not surface after hours of meshing; every such error names
// the manifest file and line. A missing or unreadable scan is not a manifest
// error: that job fails and the others run.
//
// CSV is parsed by libcsv (Debian's libcsv-dev, RFC 4180: quoted fields,
// doubled quotes, commas and line breaks inside quotes, CRLF), in strict mode
// so that a stray quote is reported instead of guessed at. Debian's only C++
// CSV library, libfccp-dev (fast-cpp-csv-parser, a 2016 snapshot), fixes the
// number and names of columns at compile time and does not accept line
// breaks inside quoted fields, so it does not fit a manifest whose option
// columns are optional. JSON lines are parsed by nlohmann-json.
#include <csv.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "Commands.hpp"
#include "Jobs.hpp"
#include "MeshOptions.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/MeshIO.hpp"

namespace isohex::cli {

namespace {

namespace fs = std::filesystem;

// A bad value in one field; the caller adds file, line and column.
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
    std::vector<std::string> items(const std::string& separators) const {
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
    const std::string& scalar() const {
        if (isList) throw FieldError{"expected one value, got a list"};
        return text;
    }
    static std::string trim(const std::string& s) {
        const auto b = s.find_first_not_of(" \t\r\n");
        if (b == std::string::npos) return {};
        return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
    }
};

double toNumber(const std::string& s) {
    const std::string t = Field::trim(s);
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(t.c_str(), &end);
    if (t.empty() || end != t.c_str() + t.size() || errno == ERANGE || !std::isfinite(v))
        throw FieldError{"expected a number, got '" + s + "'"};
    return v;
}

long long toInteger(const std::string& s) {
    const std::string t = Field::trim(s);
    char* end = nullptr;
    errno = 0;
    const long long v = std::strtoll(t.c_str(), &end, 10);
    if (t.empty() || end != t.c_str() + t.size() || errno == ERANGE)
        throw FieldError{"expected a whole number, got '" + s + "'"};
    return v;
}

bool toBool(const std::string& s) {
    std::string t = Field::trim(s);
    std::transform(t.begin(), t.end(), t.begin(), [](unsigned char c) { return std::tolower(c); });
    if (t == "1" || t == "true" || t == "yes" || t == "on" || t == "y") return true;
    if (t == "0" || t == "false" || t == "no" || t == "off" || t == "n") return false;
    throw FieldError{"expected true or false (also yes/no, 1/0), got '" + s + "'"};
}

std::string toChoice(const std::string& s, std::initializer_list<const char*> choices) {
    const std::string t = Field::trim(s);
    std::string all;
    for (const char* c : choices) {
        if (t == c) return t;
        all += std::string(all.empty() ? "" : " or ") + c;
    }
    throw FieldError{"expected " + all + ", got '" + s + "'"};
}

// Per-job values that are not mesh settings.
struct JobFields {
    std::string input;
    std::vector<std::string> outputs;
    std::string report;
    std::string plot;
    bool sawSize = false, sawLevel = false, sawIso = false;
    bool labelsOn = false;   // labels=true or a label list: a label map
    bool labelsOff = false;  // labels=false: an intensity image
};

using Setter = std::function<void(const Field&, MeshArgs&, JobFields&)>;

struct Column {
    const char* name;
    const char* help;
    Setter set;
};

// The manifest's columns (JSON keys). Names are compared after lower-casing
// and turning '-' into '_' (and dropping leading dashes), so "no-pillow" and
// "--no-pillow" name the same column as "no_pillow".
const std::vector<Column>& columns() {
    static const std::vector<Column> cols = {
        {"input", "scan to mesh (required)", [](const Field& f, MeshArgs&, JobFields& j) { j.input = f.scalar(); }},
        {"output", "output mesh file(s), several separated by ';' (required)",
         [](const Field& f, MeshArgs&, JobFields& j) { j.outputs = f.items(";"); }},
        {"report", "JSON report path", [](const Field& f, MeshArgs&, JobFields& j) { j.report = f.scalar(); }},
        {"plot", "SVG histogram path", [](const Field& f, MeshArgs&, JobFields& j) { j.plot = f.scalar(); }},
        {"iso", "surface intensity",
         [](const Field& f, MeshArgs& a, JobFields& j) {
             a.settings.select.iso = toNumber(f.scalar());
             j.sawIso = true;
         }},
        {"inside", "above or below",
         [](const Field& f, MeshArgs& a, JobFields&) {
             a.insideMode = toChoice(f.scalar(), {"above", "below"});
         }},
        {"labels", "true: read as a label map, every label",
         [](const Field& f, MeshArgs& a, JobFields& j) {
             a.labels = toBool(f.scalar());
             (a.labels ? j.labelsOn : j.labelsOff) = true;
         }},
        {"label", "labels to mesh, e.g. \"3,7\" (or 3;7)",
         [](const Field& f, MeshArgs& a, JobFields& j) {
             std::string joined;
             for (const auto& item : f.items(",; ")) {
                 toInteger(item);
                 joined += (joined.empty() ? "" : ",") + Field::trim(item);
             }
             if (joined.empty()) throw FieldError{"expected label numbers such as 3,7"};
             a.labelList = joined;
             j.labelsOn = true;
         }},
        {"keep_largest", "true/false",
         [](const Field& f, MeshArgs& a, JobFields&) { a.settings.keepLargest = toBool(f.scalar()); }},
        {"fill_pits", "true/false",
         [](const Field& f, MeshArgs& a, JobFields&) { a.settings.fillPits = toBool(f.scalar()); }},
        {"isosurface_topology", "true/false",
         [](const Field& f, MeshArgs& a, JobFields&) { a.settings.isosurfaceTopology = toBool(f.scalar()); }},
        {"min_label_voxels", "whole number",
         [](const Field& f, MeshArgs& a, JobFields&) {
             const long long v = toInteger(f.scalar());
             if (v < 0) throw FieldError{"must not be negative"};
             a.settings.select.minLabelVoxels = v;
         }},
        {"smooth", "Gaussian sigma in mm",
         [](const Field& f, MeshArgs& a, JobFields&) {
             const double v = toNumber(f.scalar());
             if (v < 0) throw FieldError{"must not be negative"};
             a.settings.select.smoothSigma = v;
         }},
        {"interpolation", "trilinear or quadratic",
         [](const Field& f, MeshArgs& a, JobFields&) {
             a.interpolation = toChoice(f.scalar(), {"trilinear", "quadratic"});
         }},
        {"series", "DICOM SeriesInstanceUID",
         [](const Field& f, MeshArgs& a, JobFields&) { a.settings.load.seriesUid = f.scalar(); }},
        {"grid", ".vdb grid name",
         [](const Field& f, MeshArgs& a, JobFields&) { a.settings.load.gridName = f.scalar(); }},
        {"volume_index", "whole number",
         [](const Field& f, MeshArgs& a, JobFields&) {
             const long long v = toInteger(f.scalar());
             if (v < 0 || v > 1000000) throw FieldError{"must be 0 or more"};
             a.settings.load.volumeIndex = static_cast<int>(v);
         }},
        {"nan_as_outside", "true/false",
         [](const Field& f, MeshArgs& a, JobFields&) { a.settings.load.nanAsOutside = toBool(f.scalar()); }},
        {"max_memory", "MB",
         [](const Field& f, MeshArgs& a, JobFields&) {
             const double v = toNumber(f.scalar());
             if (!(v > 0) || !std::isfinite(v)) throw FieldError{"must be a number of megabytes above 0"};
             a.settings.load.maxMemoryMB = v;
         }},
        {"slice_spacing", "three numbers \"X Y Z\"",
         [](const Field& f, MeshArgs& a, JobFields&) {
             const auto items = f.items(" ;,");
             if (items.size() != 3) throw FieldError{"expected three numbers X Y Z"};
             a.sliceSpacing.clear();
             for (const auto& s : items) {
                 const double v = toNumber(s);
                 if (!(v > 0)) throw FieldError{"spacings must be positive"};
                 a.sliceSpacing.push_back(v);
             }
         }},
        {"size", "element edge length (mm)",
         [](const Field& f, MeshArgs& a, JobFields& j) {
             const double v = toNumber(f.scalar());
             if (!(v > 0)) throw FieldError{"must be a positive length"};
             a.settings.size = v;
             j.sawSize = true;
         }},
        {"level", "grid level 0..10",
         [](const Field& f, MeshArgs& a, JobFields& j) {
             const long long v = toInteger(f.scalar());
             if (v < 0 || v > 10) throw FieldError{"must be between 0 and 10"};
             a.settings.level = static_cast<int>(v);
             j.sawLevel = true;
         }},
        {"method", "dual or voxel",
         [](const Field& f, MeshArgs& a, JobFields&) {
             a.settings.method = pipeline::parseMethod(toChoice(f.scalar(), {"dual", "voxel"})).value();
         }},
        {"no_pillow", "true/false",
         [](const Field& f, MeshArgs& a, JobFields&) { a.settings.pillow = !toBool(f.scalar()); }},
        {"boundary_layers", "1..16",
         [](const Field& f, MeshArgs& a, JobFields&) {
             const long long v = toInteger(f.scalar());
             if (v < 1 || v > 16) throw FieldError{"must be between 1 and 16"};
             a.settings.boundaryLayers = static_cast<int>(v);
         }},
        {"mesh_exterior", "true/false",
         [](const Field& f, MeshArgs& a, JobFields&) { a.settings.meshExterior = toBool(f.scalar()); }},
        {"fix_boundary", "true/false",
         [](const Field& f, MeshArgs& a, JobFields&) { a.settings.fixBoundary = toBool(f.scalar()); }},
        {"surface_tolerance", "voxels 0..1",
         [](const Field& f, MeshArgs& a, JobFields&) {
             const double v = toNumber(f.scalar());
             if (!(v >= 0 && v <= 1)) throw FieldError{"must be between 0 and 1 (voxels)"};
             a.settings.surfaceTolerance = v;
         }},
        {"retries", "0..16",
         [](const Field& f, MeshArgs& a, JobFields&) {
             const long long v = toInteger(f.scalar());
             if (v < 0 || v > 16) throw FieldError{"must be between 0 and 16"};
             a.settings.retries = static_cast<int>(v);
         }},
        {"retry_below", "scaled Jacobian 0..1",
         [](const Field& f, MeshArgs& a, JobFields&) {
             const double v = toNumber(f.scalar());
             if (!(v >= 0 && v <= 1)) throw FieldError{"must be between 0 and 1"};
             a.settings.retryBelow = v;
         }},
        {"no_optimize", "true/false",
         [](const Field& f, MeshArgs& a, JobFields&) { a.settings.optimize = !toBool(f.scalar()); }},
    };
    return cols;
}

// Options that apply to the whole run, not to one job.
const std::set<std::string>& globalOnly() {
    static const std::set<std::string> g = {"threads", "quiet", "q", "log_json", "force"};
    return g;
}

std::string normalizeName(std::string s) {
    s = Field::trim(s);
    while (!s.empty() && s.front() == '-') s.erase(s.begin());
    for (char& c : s) c = c == '-' ? '_' : static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

std::string knownColumns() {
    std::string s;
    for (const auto& c : columns()) s += std::string(s.empty() ? "" : ", ") + c.name;
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

const Column& findColumn(const std::string& file, std::size_t line, const std::string& raw, const char* kind) {
    const std::string name = normalizeName(raw);
    if (globalOnly().count(name))
        fail(file, line,
             std::string(kind) + " '" + raw + "' is an option of the whole run; give --" +
                 (name == "q"          ? std::string("quiet")
                  : name == "log_json" ? std::string("log-json")
                                       : name) +
                 " on the command line");
    for (const auto& c : columns())
        if (name == c.name) return c;
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

// ---------------------------------------------------------------------------
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
    std::vector<const Column*> cols;
    std::set<std::string> seen;
    for (const auto& h : header) {
        if (Field::trim(h).empty()) fail(file, headerLine, "the header has an empty column name");
        const Column& c = findColumn(file, headerLine, h, "column");
        if (!seen.insert(c.name).second) fail(file, headerLine, std::string("column '") + c.name + "' appears twice");
        cols.push_back(&c);
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
            row.fields.emplace_back(cols[i]->name, Field{cells[i], {}, false});
        rows.push_back(std::move(row));
    }
    return rows;
}

// ---------------------------------------------------------------------------
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
        if (Field::trim(lineText).empty()) continue;
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
            const Column& c = findColumn(file, line, key, "key");
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
            row.fields.emplace_back(c.name, std::move(f));
        }
        rows.push_back(std::move(row));
    }
    return rows;
}

// ---------------------------------------------------------------------------

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

std::vector<Job> readManifest(const std::string& file, const MeshArgs& defaults) {
    const std::string ext = lowerExtension(file);
    std::vector<Row> rows;
    if (ext == ".csv")
        rows = readCsv(file);
    else if (ext == ".jsonl" || ext == ".ndjson")
        rows = readJsonLines(file);
    else
        throw Error(
            file + ": unknown manifest type '" + ext +
            "': name it .csv (a header row, then one job per row) or .jsonl / .ndjson (one JSON object per line)");
    const fs::path base = fs::path(file).parent_path();
    std::vector<Job> jobs;
    std::map<std::string, std::size_t> written;  // output path -> line of the job writing it
    for (const Row& row : rows) {
        Job job;
        job.args = defaults;
        JobFields j;
        for (const auto& [name, field] : row.fields) {
            if (field.empty()) continue;  // not given: the command line's value
            const auto& cols = columns();
            const auto c = std::find_if(cols.begin(), cols.end(), [&](const Column& k) { return name == k.name; });
            try {
                c->set(field, job.args, j);
            } catch (const FieldError& e) {
                fail(file, row.line, "column '" + name + "': " + e.message);
            }
        }
        // A job's own choice replaces the command line's rather than clashing with it.
        if (j.sawSize && j.sawLevel) fail(file, row.line, "give either size or level, not both");
        if (j.sawSize) job.args.settings.level.reset();
        if (j.sawLevel) job.args.settings.size.reset();
        if (j.sawIso && j.labelsOn)
            fail(file, row.line, "iso applies to intensity images, labels/label to label maps; give one");
        if (j.labelsOn && j.labelsOff) fail(file, row.line, "labels is false but label lists labels");
        if (j.sawIso || j.labelsOff) {
            job.args.labels = false;
            job.args.labelList.clear();
        }
        if (j.labelsOn) job.args.settings.select.iso.reset();
        if (j.input.empty()) fail(file, row.line, "no input: every job needs an 'input' scan");
        if (j.outputs.empty())
            fail(file, row.line, "no output: every job needs an 'output' mesh file (several separated by ';')");
        try {
            MeshArgs check = job.args;
            check.finish();
        } catch (const Error& e) {
            fail(file, row.line, e.what());
        }
        job.input = resolve(base, j.input);
        for (const auto& o : j.outputs) {
            job.outputs.push_back(resolve(base, o));
            try {
                io::formatFromPath(job.outputs.back());
            } catch (const Error& e) {
                fail(file, row.line, e.what());
            }
        }
        job.report = resolve(base, j.report);
        job.plot = resolve(base, j.plot);
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

std::string manifestHelp() {
    std::string s =
        "\nManifest: a .csv file (a header row naming the columns, then one job per row) or a .jsonl/.ndjson file\n"
        "(one JSON object per line with the same keys). Paths are relative to the manifest's folder; output\n"
        "folders are created. An empty "
        "field (or a missing key, or null) takes the value given on the command line. Columns:\n";
    for (const auto& c : columns())
        s += std::string("  ") + c.name + std::string(18 - std::min<std::size_t>(17, std::string(c.name).size()), ' ') +
             c.help + "\n";
    s +=
        "Example (CSV):\n"
        "  input,output,size,label\n"
        "  ct1.nii.gz,ct1.vtu;ct1.exo,2,\n"
        "  atlas.nii.gz,atlas.vtu,,\"3,7\"\n"
        "Example (JSON lines):\n"
        "  {\"input\": \"ct1.nii.gz\", \"output\": [\"ct1.vtu\", \"ct1.exo\"], \"size\": 2, \"report\": \"ct1.json\"}\n"
        "A job whose outputs (and report and plot) are newer than its input is skipped; editing the\n"
        "manifest does not make outputs stale, so rerun with --force after changing a job's options.";
    return s;
}

struct BatchCommand {
    std::string manifest;
    MeshArgs args;
};

}  // namespace

void addBatchCommand(CLI::App& app) {
    auto c = std::make_shared<BatchCommand>();
    CLI::App* cmd = app.add_subcommand(
        "batch", "Mesh every job of a CSV or JSON-lines manifest; continues past failures, skips up-to-date outputs");
    cmd->add_option("manifest", c->manifest, "Jobs: a .csv file or a .jsonl/.ndjson file (see below)")->required();
    addMeshOptions(cmd, c->args);
    addRunOptions(cmd, c->args);
    cmd->footer(manifestHelp());
    cmd->callback([c] {
        const std::vector<Job> jobs = readManifest(c->manifest, c->args);
        applyThreads(c->args.threads);
        // Output folders are made here (as workflow engines do); a folder that cannot be made
        // fails only its job, when the job writes there.
        for (const Job& job : jobs) {
            std::vector<std::string> all = job.outputs;
            all.push_back(job.report);
            all.push_back(job.plot);
            for (const auto& o : all) {
                const fs::path parent = fs::path(o).parent_path();
                std::error_code ec;
                if (!o.empty() && !parent.empty()) fs::create_directories(parent, ec);
            }
        }
        if (jobs.empty()) {
            ProgressSink sink(c->args.progressMode());
            sink.note("warning", c->manifest + ": the manifest lists no jobs");
        }
        if (runJobs(jobs, c->args.force, c->args.progressMode()) > 0) pendingExitCode() = kExitError;
    });
}

}  // namespace isohex::cli

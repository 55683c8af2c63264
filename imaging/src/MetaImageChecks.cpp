// MetaImage checks around ITK's MetaIO reader (see FormatChecks.hpp).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <zlib.h>

#include "DataFilePlace.hpp"
#include "FormatChecks.hpp"

namespace isohex::imaging::detail {
namespace {

// A MetaImage header: its "Key = Value" lines up to ElementDataFile (the
// last one; the data or, for LIST, the file names follow it), values
// trimmed, and where that line ends. Both MetaImage checks read it.
struct MetaHeader {
    std::map<std::string, std::string> values;
    bool hasDataFile = false;
    std::string dataFile;
    std::uint64_t dataStart = 0;  // first byte after the ElementDataFile line

    static std::string trim(std::string t) {
        while (!t.empty() && std::isspace(static_cast<unsigned char>(t.back()))) t.pop_back();
        while (!t.empty() && std::isspace(static_cast<unsigned char>(t.front()))) t.erase(0, 1);
        return t;
    }
    explicit MetaHeader(const std::string& file) {
        std::ifstream in(file, std::ios::binary);
        std::string line;
        for (int n = 0; n < 200 && std::getline(in, line); ++n) {  // headers are a few dozen lines
            const auto eq = line.find('=');
            if (eq == std::string::npos) continue;
            const std::string key = trim(line.substr(0, eq)), value = trim(line.substr(eq + 1));
            if (key == "ElementDataFile") {
                hasDataFile = true;
                dataFile = value;
                dataStart = static_cast<std::uint64_t>(in.tellg());
                return;
            }
            values[key] = value;
        }
    }
    const std::string* get(const char* key) const {
        const auto it = values.find(key);
        return it == values.end() ? nullptr : &it->second;
    }
};

// Where a MetaImage's voxel data lies: its file (the header's own for LOCAL),
// the byte it starts at, and the bytes from there to the end of that file.
struct MetaData {
    std::filesystem::path path;
    bool local = false;
    std::uint64_t start = 0, available = 0;
};

// Compressed MetaImage data is inflated here once before MetaIO reads it:
// MetaIO does not report a damaged zlib stream, and without a
// CompressedDataSize (or with 0) it reads wrong voxel values: a corrupted
// stream would be meshed as it comes out, and a missing size or gzip data in
// place of zlib gives NaN voxels and a misleading message about those.
// zlib's Adler-32 check catches damage; the stream must end within
// CompressedDataSize, and the inflated size must be what the header's sizes
// need.
void checkMetaImageInflates(const std::string& file, const MetaData& data, const std::string* sizeField,
                            std::uint64_t dataBytes) {
    const std::uint64_t declared = sizeField ? std::strtoull(sizeField->c_str(), nullptr, 10) : 0;
    if (declared == 0)  // MetaIO then inflates the wrong bytes (wrong voxels, no message)
        throw Error(file + ": CompressedData is True but CompressedDataSize is " + (sizeField ? "0" : "missing") +
                    ", and MetaIO then reads wrong voxel values. Add the line 'CompressedDataSize = " +
                    std::to_string(data.available) + "' (the bytes of compressed data" +
                    (data.local ? " after the header" : " in " + data.path.filename().string()) +
                    ") before ElementDataFile, or save the image again.");
    std::ifstream in(data.path, std::ios::binary);
    in.seekg(static_cast<std::streamoff>(data.start));
    z_stream z{};
    if (inflateInit(&z) != Z_OK) return;
    std::vector<unsigned char> input(1 << 20), output(1 << 20);
    std::uint64_t left = declared, produced = 0;
    int rc = Z_OK;
    std::string problem;
    while (rc != Z_STREAM_END && problem.empty()) {
        if (z.avail_in == 0) {
            std::uint64_t got = 0;
            if (left > 0) {
                in.read(reinterpret_cast<char*>(input.data()),
                        static_cast<std::streamsize>(std::min<std::uint64_t>(left, input.size())));
                got = static_cast<std::uint64_t>(in.gcount());
            }
            if (got == 0) {
                problem = "the compressed data ends before its stream does";
                break;
            }
            left -= got;
            z.next_in = input.data();
            z.avail_in = static_cast<uInt>(got);
        }
        z.next_out = output.data();
        z.avail_out = static_cast<uInt>(output.size());
        rc = inflate(&z, Z_NO_FLUSH);
        produced += output.size() - z.avail_out;
        if (rc != Z_OK && rc != Z_STREAM_END)
            problem = std::string("the compressed data is damaged (zlib: ") + (z.msg ? z.msg : "error " + std::to_string(rc)) + ")";
    }
    inflateEnd(&z);
    if (!problem.empty())
        throw Error(file + ": " + problem + " after " + std::to_string(produced) +
                    " uncompressed bytes. Copy or export the file again.");
    if (produced != dataBytes)
        throw Error(file + ": the compressed data inflates to " + std::to_string(produced) + " bytes but the header's "
                    "DimSize, ElementType and channels need " + std::to_string(dataBytes) +
                    ". The header does not describe the data; export the file again.");
}

}  // namespace

// MetaImage: the data follows the header line "ElementDataFile = ..." (LOCAL)
// or sits in the named file; MetaIO reads short data with only a warning.
void checkMetaImageSize(const std::string& file, std::uint64_t dataBytes) {
    const MetaHeader header(file);
    std::string dataFile = header.dataFile;
    const std::string* c = header.get("CompressedData");
    const bool compressed = c && (*c == "True" || *c == "true");
    const std::string* cs = header.get("CompressedDataSize");
    if (dataFile.empty() || dataFile.rfind("LIST", 0) == 0 || dataFile.find('%') != std::string::npos) return;
    MetaData data;
    data.local = dataFile == "LOCAL" || dataFile == "Local" || dataFile == "local";
    data.path = data.local ? std::filesystem::path(file) : std::filesystem::path(file).parent_path() / dataFile;
    data.start = data.local ? header.dataStart : 0;
    std::error_code ec;
    const std::uint64_t have = std::filesystem::file_size(data.path, ec);
    if (ec)
        throw Error(file + ": its voxel data file '" + data.path.string() +
                    "' is missing; keep the .mhd header and its data file together.");
    data.available = have - std::min(have, data.start);
    const std::uint64_t need = compressed ? (cs ? std::strtoull(cs->c_str(), nullptr, 10) : 0) : dataBytes;
    if (need > 0 && have < data.start + need) throwTruncated(file, data.start + need, have, "bytes");
    if (compressed) checkMetaImageInflates(file, data, cs, dataBytes);
}

namespace {

// What checkMetaImageHeader's phases share: the header, read as MetaIO reads
// it, and where its data files are looked for.
struct MetaLayout {
    std::string file;
    bool allowDataOutside = false;
    MetaHeader header;
    std::filesystem::path dir;  // the header's folder
    long long ndims = 0;
    std::vector<long long> dims;  // DimSize; 0 for a size that is not a positive whole number
    long long slices = 0;         // the last dimension's size, when DimSize gives NDims sizes

    MetaLayout(const std::string& f, bool allowOutside)
        : file(f), allowDataOutside(allowOutside), header(f), dir(std::filesystem::path(f).parent_path()) {}
    [[noreturn]] void fail(const std::string& what) const { throw Error(file + ": " + what); }
    // A data file named in the header must be a regular file beside it.
    void requireFile(const std::string& name) const { checkDataFilePlace(file, name, allowDataOutside); }
};

// NDims (1 to 8: MetaIO loops for ever on 0 or less) and DimSize.
void readDimensions(MetaLayout& m) {
    if (const std::string* value = m.header.get("NDims")) {
        std::istringstream v(*value);
        if (!(v >> m.ndims) || m.ndims < 1 || m.ndims > 8)
            m.fail("the MetaImage header says NDims = " + *value +
                   "; it must be the number of image dimensions (3 for a volume). Fix the header and retry.");
    }
    if (const std::string* value = m.header.get("DimSize")) {
        std::istringstream v(*value);
        for (double d; v >> d;) m.dims.push_back(d >= 1 && d < 9e18 && d == std::floor(d) ? static_cast<long long>(d) : 0);
    }
    m.slices = m.ndims >= 1 && static_cast<long long>(m.dims.size()) >= m.ndims ? m.dims[m.ndims - 1] : 0;
}

// DimSize gives NDims positive sizes, the data is binary (MetaIO crashes on
// ASCII data) and ElementDataFile names something.
void checkDataDeclaration(const MetaLayout& m) {
    if (m.ndims >= 1 && (static_cast<long long>(m.dims.size()) < m.ndims ||
                         std::any_of(m.dims.begin(), m.dims.begin() + m.ndims, [](long long d) { return d < 1; })))
        m.fail("the MetaImage header's DimSize does not give " + std::to_string(m.ndims) +
               " positive sizes; fix the header and retry.");
    // MetaIO: binary when the value starts with T, t or 1
    const std::string* binaryValue = m.header.get("BinaryData");
    const bool binary = !binaryValue || (!binaryValue->empty() && ((*binaryValue)[0] == 'T' || (*binaryValue)[0] == 't' ||
                                                                   (*binaryValue)[0] == '1'));
    if (!binary)
        m.fail("ASCII MetaImage data (BinaryData = False) is not supported: ITK's reader fails on it. Save the image "
               "with binary data (e.g. SimpleITK or 3D Slicer) and retry.");
    if (m.header.dataFile.empty())
        m.fail("the MetaImage header's ElementDataFile is empty; it must be LOCAL, LIST or the data file's name.");
}

// "LIST nD": the file names follow the header, one a line. As MetaIO: they
// are files of n dimensions (default NDims-1), one per index of the
// dimensions above; a last name without a line end is not read.
void checkListedFiles(const MetaLayout& m) {
    const std::string& dataFile = m.header.dataFile;
    std::ifstream in(m.file, std::ios::binary);
    in.seekg(static_cast<std::streamoff>(m.header.dataStart));
    long long fileDim = m.ndims - 1;
    {
        std::istringstream w(dataFile.substr(4));
        double d = 0;
        if (w >> d && d >= 1 && d <= double(m.ndims)) fileDim = static_cast<long long>(d);
    }
    long long files = 1;
    for (long long a = fileDim; a < m.ndims && a < static_cast<long long>(m.dims.size()); ++a)
        files = std::min<long long>(files * std::max<long long>(m.dims[static_cast<std::size_t>(a)], 1), 1LL << 40);
    long long listed = 0;
    std::string line;
    while (listed < files && std::getline(in, line)) {
        if (in.eof()) break;  // no line end: MetaIO stops before it
        const std::string name = MetaHeader::trim(line);
        if (name.empty()) continue;
        m.requireFile(name);
        ++listed;
    }
    if (listed < files)
        m.fail("the MetaImage header lists " + std::to_string(listed) + " data file(s) (each on its own line) for " +
               std::to_string(files) + " needed; every slice needs its file.");
}

// "pattern [first [last [step]]]", read as MetaIO reads it: first 1, last
// first + slices - 1, step (last - first) / slices with three words. MetaIO
// loops for ever on a step of 0 and reads nothing for a negative one; every
// slice's file must exist.
void checkFilePattern(const MetaLayout& m) {
    const std::string& dataFile = m.header.dataFile;
    const long long slices = m.slices;
    std::istringstream v(dataFile);
    std::string pattern;
    v >> pattern;
    std::vector<double> words;
    for (double d; v >> d;) words.push_back(d);
    for (double d : words)
        if (!(std::fabs(d) < 1e9)) m.fail("the MetaImage file pattern '" + dataFile + "' has a number out of range; fix the header.");
    long long first = 1, last = slices, step = 1;
    if (words.size() >= 1) {
        first = static_cast<long long>(words[0]);
        last = first + slices - 1;
    }
    if (words.size() >= 2) {
        last = static_cast<long long>(words[1]);
        step = slices > 0 ? (last - first) / slices : 1;
    }
    if (words.size() >= 3) step = static_cast<long long>(words[2]);
    // One integer conversion (%d, %03d ...) and nothing else a printf
    // would read an argument for.
    if (!isOneIntegerPattern(pattern))
        m.fail("the MetaImage file pattern '" + pattern + "' must hold one integer field such as %03d; fix the header.");
    if (step <= 0 || last < first)
        m.fail("the MetaImage file pattern '" + dataFile + "' steps by " + std::to_string(step) + " from " +
               std::to_string(first) + " to " + std::to_string(last) +
               ", which names no file or never ends; write the pattern as 'name first last step' with a step "
               "of 1 or more and fix the header.");
    if ((last - first) / step + 1 < slices)
        m.fail("the MetaImage file pattern '" + dataFile + "' names " + std::to_string((last - first) / step + 1) +
               " file(s) for " + std::to_string(slices) + " slices; every slice needs its file.");
    for (long long i = first, k = 0; k < slices; i += step, ++k) {
        char name[4096];
        std::snprintf(name, sizeof name, pattern.c_str(), static_cast<int>(i));
        m.requireFile(name);
    }
}

// One data file (or LOCAL): the file must be a regular file beside the
// header, and HeaderSize (bytes skipped before the data; -1: the data ends
// the file) must be -1 or more and end inside it.
void checkHeaderSize(const MetaLayout& m) {
    const std::string& dataFile = m.header.dataFile;
    const bool local = dataFile == "LOCAL" || dataFile == "Local" || dataFile == "local";
    if (!local) m.requireFile(dataFile);
    long long headerSize = 0;
    if (const std::string* value = m.header.get("HeaderSize")) std::istringstream(*value) >> headerSize;
    if (headerSize < -1)
        m.fail("the MetaImage header's HeaderSize is " + std::to_string(headerSize) +
               "; it must be the bytes before the data (0 or more, or -1 for data that ends the file). "
               "Fix the header and retry.");
    if (headerSize <= 0) return;
    const std::filesystem::path data = local ? std::filesystem::path(m.file) : m.dir / dataFile;
    std::error_code ec;
    const auto have = std::filesystem::file_size(data, ec);
    if (!ec && static_cast<std::uint64_t>(headerSize) >= have)
        m.fail("the MetaImage header's HeaderSize (" + std::to_string(headerSize) + " bytes) is past the end of '" +
               data.string() + "' (" + std::to_string(have) + " bytes); fix the header.");
}

}  // namespace

// MetaImage header fields ITK's MetaIO mishandles without an exception:
// NDims of 0 or less loops forever, a file pattern with step 0 loops
// forever printing errors, ASCII data (BinaryData = False) crashes the
// process (ITK 5.2/5.3), and a LIST or pattern naming missing files, an empty
// ElementDataFile or a HeaderSize past the end of the data leave voxels
// unread, which it reports only as a warning; without ElementDataFile it
// aborts the process. Data files must be regular files in the header's
// folder (checkDataFilePlace). Checked before MetaIO reads
// the header. (The data size of LOCAL and single-file data is checked after,
// by checkMetaImageSize, which needs the element size.)
void checkMetaImageHeader(const std::string& file, bool allowDataOutside) {
    MetaLayout m(file, allowDataOutside);
    readDimensions(m);
    if (!m.header.hasDataFile)  // MetaIO reads past its buffer (a fortified abort) looking for it
        m.fail("the MetaImage header has no ElementDataFile line (LOCAL, LIST or the data file's name), so it "
               "says nowhere where its voxels are; fix the header or export the image again.");
    checkDataDeclaration(m);
    if (m.header.dataFile.rfind("LIST", 0) == 0)
        checkListedFiles(m);
    else if (m.header.dataFile.find('%') != std::string::npos)
        checkFilePattern(m);
    else
        checkHeaderSize(m);
}

}  // namespace isohex::imaging::detail

// Every ITK reader of the module lives in this one translation unit (ITK's
// templates are expensive to compile). It turns a file or folder into a
// RawVolume: a dense float or int32 array plus origin, spacing and direction.
#include <cstdarg>
#include <cstdio>
#include <algorithm>
#include <cmath>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <type_traits>
#include <memory>
#include <limits>
#include <locale>
#include <map>
#include <set>
#include <sstream>

#include <gdcmMediaStorage.h>
#include <gdcmReader.h>
#include <gdcmScanner.h>
#include <gdcmTrace.h>
#include <itkGDCMImageIO.h>
#include <itkGDCMSeriesFileNames.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkImageIOFactory.h>
#include <itkImageSeriesReader.h>
#include <itkTIFFImageIO.h>
#include <itkVector.h>
#include <itkVectorImage.h>
#include <tiffio.h>
#include <zlib.h>

#include "RawVolume.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"

namespace isohex::imaging::detail {
namespace {

using FloatImage3 = itk::Image<float, 3>;
using VectorImage4 = itk::VectorImage<float, 4>;

std::string formatName(const itk::ImageIOBase& io) {
    const std::string n = io.GetNameOfClass();
    if (n == "NiftiImageIO") return "NIfTI";
    if (n == "NrrdImageIO") return "NRRD";
    if (n == "MetaImageIO") return "MetaImage";
    if (n == "TIFFImageIO") return "TIFF";
    if (n == "GDCMImageIO") return "DICOM";
    return n;
}

std::string componentName(itk::IOComponentEnum c) {
    switch (c) {
        case itk::IOComponentEnum::UCHAR: return "uint8";
        case itk::IOComponentEnum::CHAR: return "int8";
        case itk::IOComponentEnum::USHORT: return "uint16";
        case itk::IOComponentEnum::SHORT: return "int16";
        case itk::IOComponentEnum::UINT: return "uint32";
        case itk::IOComponentEnum::INT: return "int32";
        case itk::IOComponentEnum::ULONG: return "uint64";
        case itk::IOComponentEnum::LONG: return "int64";
        case itk::IOComponentEnum::ULONGLONG: return "uint64";
        case itk::IOComponentEnum::LONGLONG: return "int64";
        case itk::IOComponentEnum::FLOAT: return "float32";
        case itk::IOComponentEnum::DOUBLE: return "float64";
        default: return "unknown";
    }
}

bool isIntegerComponent(itk::IOComponentEnum c) {
    return c != itk::IOComponentEnum::FLOAT && c != itk::IOComponentEnum::DOUBLE &&
           c != itk::IOComponentEnum::UNKNOWNCOMPONENTTYPE;
}

std::string describe(const itk::ExceptionObject& e) {
    std::string d = e.GetDescription();
    while (!d.empty() && (d.back() == '\n' || d.back() == ' ')) d.pop_back();
    return d;
}

// Label maps travel as float through ITK (one read path for every format);
// float holds every integer up to 2^24 exactly, which bounds the label values.
void convertToLabels(RawVolume& raw, const std::string& file, bool integerFile) {
    constexpr float kMaxExact = 16777216.0f;
    std::int64_t bad = 0;
    float example = 0.0f;
    raw.labels.resize(raw.values.size());
    for (std::size_t i = 0; i < raw.values.size(); ++i) {
        const float v = raw.values[i];
        if (!std::isfinite(v) || std::nearbyint(v) != v || std::fabs(v) > kMaxExact) {
            if (bad++ == 0) example = v;
            continue;
        }
        raw.labels[i] = static_cast<std::int32_t>(v);
    }
    if (bad > 0) {
        std::ostringstream m;
        m << file << ": cannot read as a label map: " << bad << " voxels are not integer labels"
          << " (e.g. " << example << ")"
          << (integerFile ? ", or exceed 16777216" : "; the image holds real-valued intensities")
          << ". Read it as an intensity image (no labels option) and select by iso value instead.";
        throw Error(m.str());
    }
    raw.values.clear();
    raw.values.shrink_to_fit();
}

template <class ImageT>
void copyGeometry(const ImageT& image, RawVolume& raw) {
    const auto& o = image.GetOrigin();
    const auto& s = image.GetSpacing();
    const auto& d = image.GetDirection();
    for (int a = 0; a < 3; ++a) {
        raw.origin[a] = o[a];
        raw.spacing[a] = s[a];
        for (int b = 0; b < 3; ++b) raw.direction[3 * a + b] = d(a, b);
    }
}

void checkGeometry(const RawVolume& raw, const std::string& file) {
    for (int a = 0; a < 3; ++a) {
        if (!(raw.spacing[a] > 0.0) || !std::isfinite(raw.spacing[a])) {
            std::ostringstream m;
            m << file << ": voxel spacing along axis " << a << " is " << raw.spacing[a]
              << "; it must be a positive number. Fix the header (e.g. pixdim in NIfTI) and retry.";
            throw Error(m.str());
        }
        if (!std::isfinite(raw.origin[a])) {
            throw Error(file + ": the image origin is not a finite number; fix the header and retry.");
        }
        // OpenVDB's transform (double precision) refuses scales near 1e-30 or
        // an origin near 1e30 with an exception; no scanner writes either.
        if (raw.spacing[a] < 1e-9 || raw.spacing[a] > 1e9) {
            std::ostringstream m;
            m << file << ": voxel spacing along axis " << a << " is " << raw.spacing[a]
              << "; isohex reads spacings from 1e-9 to 1e9. Fix the header or its units (for a folder of slices, ";
            throw SettingError({m.str(), Setting::SliceSpacing, ") and retry."});
        }
        if (std::fabs(raw.origin[a]) > 1e12) {
            std::ostringstream m;
            m << file << ": the image origin is " << raw.origin[a] << " along axis " << a
              << "; isohex reads origins up to 1e12 in size. Fix the header (or its units) and retry.";
            throw Error(m.str());
        }
    }
    const auto& D = raw.direction;
    const double det = D[0] * (D[4] * D[8] - D[5] * D[7]) - D[1] * (D[3] * D[8] - D[5] * D[6]) +
                       D[2] * (D[3] * D[7] - D[4] * D[6]);
    if (!(std::fabs(det) > 1e-6)) {
        throw Error(file + ": the direction cosines are singular (determinant " +
                    std::to_string(det) + "); fix the orientation in the header and retry.");
    }
    // OpenVDB refuses a transform whose determinant (the voxel volume) is
    // below 3e-15 (3 x its double tolerance): micrometre voxels given in
    // metres (1e-6 m: 1e-18).
    const double voxelVolume = raw.spacing[0] * raw.spacing[1] * raw.spacing[2] * std::fabs(det);
    if (voxelVolume < 3e-15) {
        std::ostringstream m;
        m << file << ": the voxel volume is " << voxelVolume << " (spacing " << raw.spacing[0] << " x "
          << raw.spacing[1] << " x " << raw.spacing[2]
          << "), below the 3e-15 cubic units OpenVDB's grid transform takes; the spacing is probably in metres. "
             "Give it in millimetres (spacing and origin times 1000) and retry.";
        throw Error(m.str());
    }
}

// The start of a NIfTI-1 (348-byte) or NIfTI-2 (540-byte) header, read with
// gzread (which reads an uncompressed file as it is, so one path serves .nii
// and .nii.gz), its byte order and version worked out. The checks below read
// their fields from it.
struct NiftiHeader {
    unsigned char bytes[548] = {};
    int got = 0;            // bytes read
    bool known = false;     // sizeof_hdr is 348 or 540 in either byte order
    bool v1 = true, swap = false;
    bool compressed = false;  // gzip data, whatever the name says

    explicit NiftiHeader(const std::string& file) {
        gzFile gz = gzopen(file.c_str(), "rb");
        if (!gz) return;
        got = gzread(gz, bytes, sizeof bytes);
        compressed = gzdirect(gz) == 0;
        gzclose(gz);
        if (got < 4) return;
        const auto size = field<std::uint32_t>(0);
        const auto swapped = __builtin_bswap32(size);
        swap = size != 348 && size != 540;
        known = swap ? swapped == 348 || swapped == 540 : true;
        v1 = (swap ? swapped : size) == 348;
    }
    // The value of type T at byte `at`, in the file's byte order.
    template <class T>
    T field(int at) const {
        unsigned char b[sizeof(T)];
        std::memcpy(b, bytes + at, sizeof(T));
        if (swap) std::reverse(b, b + sizeof(T));
        T v;
        std::memcpy(&v, b, sizeof(T));
        return v;
    }
    // A real field at byte at1 (NIfTI-1, float) or at2 (NIfTI-2, double).
    double real(int at1, int at2) const { return v1 ? double(field<float>(at1)) : field<double>(at2); }
    // vox_offset as stored (float in NIfTI-1, int64 in NIfTI-2).
    double voxOffset() const { return v1 ? double(field<float>(108)) : double(field<std::uint64_t>(168)); }
};

[[noreturn]] void truncated(const std::string& file, std::uint64_t need, std::uint64_t have,
                            const char* what) {
    throw Error(file + ": the voxel data is truncated: the header promises " + std::to_string(need) +
                " " + what + " but the file has " + std::to_string(have) +
                ". Copy or export the file again.");
}

// Uncompressed bytes in a gzip file, reading it through to the end. A cut
// gzip stream ends early, which the NIfTI reader would zero-fill silently.
// Damaged compressed data (zlib's Z_DATA_ERROR: a bad CRC or length check,
// an invalid block) is refused here with its own message; it used to be
// reported as a truncation, or, with the damage in the last check bytes,
// not at all (ITK reads the voxels before the check).
std::uint64_t gunzippedSize(const std::string& file) {
    gzFile gz = gzopen(file.c_str(), "rb");
    if (!gz) return 0;
    std::vector<char> chunk(1 << 20);
    std::uint64_t total = 0;
    int n;
    while ((n = gzread(gz, chunk.data(), static_cast<unsigned>(chunk.size()))) > 0) total += n;
    int code = Z_OK;
    std::string message = n < 0 ? gzerror(gz, &code) : "";
    gzclose(gz);
    if (message.rfind(file + ": ", 0) == 0) message.erase(0, file.size() + 2);  // zlib puts the path first
    if (code == Z_DATA_ERROR)
        throw Error(file + ": the compressed data is damaged (zlib: " + message +
                    "). Copy or export the file again.");
    return total;
}

// NIfTI's reader zero-fills missing voxel bytes with only a debug message, so
// check the size against the header ourselves: the file's size, or for a
// .nii.gz its uncompressed size (reading it through: a cut gzip stream ends
// early), against vox_offset plus the voxel bytes.
void checkNiftiDataSize(const std::string& file, std::uint64_t dataBytes, bool gzipped) {
    const NiftiHeader h(file);
    if (h.got < 352 || !h.known) return;  // too short for a header; ITK has judged it already
    const double voxOffset = h.voxOffset();
    if (!gzipped && (h.compressed || !(voxOffset >= 0))) return;  // (a gzip stream named .nii: its file size says nothing)
    const std::uint64_t need = std::uint64_t(gzipped ? std::max(voxOffset, 352.0) : voxOffset) + dataBytes;
    const std::uint64_t have = gzipped ? gunzippedSize(file) : std::filesystem::file_size(file);
    if (have < need) truncated(file, need, have, gzipped ? "uncompressed bytes" : "bytes");
}


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
// CompressedDataSize (or with 0) it reads wrong voxel values. A corrupted
// stream was meshed as it came out, and a missing size or gzip data in place
// of zlib gave NaN voxels and a message about those (the corrupted-input
// survey). zlib's Adler-32 check catches damage; the stream must end within
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
    if (need > 0 && have < data.start + need) truncated(file, data.start + need, have, "bytes");
    if (compressed) checkMetaImageInflates(file, data, cs, dataBytes);
}

// NIfTI orientation fields that are not finite make ITK's reader abort the
// process (vnl's matrix code calls abort() on a NaN in srow_x; found by a
// helper's corrupted-input survey, and a batch died with it). Checked before
// ITK reads the header: pixdim[1..3] always, the quaternion and offsets when
// qform_code is set, the affine rows when sform_code is set. gzread reads an
// uncompressed file as it is, so one path serves .nii and .nii.gz.
void checkNiftiOrientation(const std::string& file) {
    const NiftiHeader h(file);
    if (h.got < 348 || !h.known || (!h.v1 && h.got < 540)) return;  // ITK judges short headers
    auto require = [&](const char* field, int k, double v) {
        if (!std::isfinite(v))
            throw Error(file + ": the NIfTI header's " + field + "[" + std::to_string(k) + "] is " +
                        (std::isnan(v) ? "NaN" : "infinite") +
                        "; the image orientation cannot be read. Fix or re-export the header and retry.");
    };
    for (int k = 1; k <= 3; ++k) require("pixdim", k, h.real(76 + 4 * k, 104 + 8 * k));
    const int qform = h.v1 ? h.field<std::int16_t>(252) : h.field<std::int32_t>(344);
    const int sform = h.v1 ? h.field<std::int16_t>(254) : h.field<std::int32_t>(348);
    if (qform > 0) {
        for (int k = 0; k < 3; ++k) require("quatern_bcd", k, h.real(256 + 4 * k, 352 + 8 * k));
        for (int k = 0; k < 3; ++k) require("qoffset_xyz", k, h.real(268 + 4 * k, 376 + 8 * k));
    }
    if (sform > 0) {
        const char* rows[3] = {"srow_x", "srow_y", "srow_z"};
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 4; ++k) require(rows[r], k, h.real(280 + 16 * r + 4 * k, 400 + 32 * r + 8 * k));
    }
}

// nifti1_io (inside ITK's NIfTI reader) replaces NaN and infinite float
// voxels with 0, with only a debug message, so a NIfTI scan never reached
// isohex's NaN policy (refuse, or outside with --nan-as-outside) and was
// meshed with zeros in the holes. This reads the float voxels of the chosen
// volume (`frame` of `frames`, component `comp`) again and puts NaN back
// where the file has a non-finite value.
void restoreNiftiNonFinite(const std::string& file, std::vector<float>& values, std::int64_t frame,
                           std::int64_t frames, int comp) {
    const NiftiHeader h(file);
    if (h.got < 348 || !h.known || (!h.v1 && h.got < 540)) return;
    const auto dt = h.field<std::uint16_t>(h.v1 ? 70 : 12);
    if (dt != 16 && dt != 64) return;  // only float32 and float64 voxels can be non-finite
    const double stored = h.voxOffset();
    if (!std::isfinite(stored)) return;
    const double voxOffset = std::max(stored, h.v1 ? 352.0 : 544.0);
    gzFile gz = gzopen(file.c_str(), "rb");
    if (!gz) return;
    std::unique_ptr<std::remove_pointer_t<gzFile>, int (*)(gzFile)> guard(gz, gzclose);
    const bool swap = h.swap;
    const std::size_t width = dt == 16 ? 4 : 8;
    const auto n = static_cast<std::int64_t>(values.size());
    // NIfTI order: x fastest, then y, z, t (frames), then the components.
    const std::int64_t first = (std::int64_t(comp) * frames + frame) * n;
    if (gzseek(gz, static_cast<z_off_t>(voxOffset + double(first) * double(width)), SEEK_SET) < 0) return;
    std::vector<unsigned char> chunk(width * 65536);
    for (std::int64_t i = 0; i < n;) {
        const std::int64_t count = std::min<std::int64_t>(65536, n - i);
        const int want = static_cast<int>(count * static_cast<std::int64_t>(width));
        if (gzread(gz, chunk.data(), static_cast<unsigned>(want)) != want) return;  // short: the size checks report it
        for (std::int64_t k = 0; k < count; ++k) {
            const unsigned char* b = chunk.data() + k * static_cast<std::int64_t>(width);
            bool finite;
            if (width == 4) {
                std::uint32_t u;
                std::memcpy(&u, b, 4);
                if (swap) u = __builtin_bswap32(u);
                finite = (u & 0x7f800000u) != 0x7f800000u;
            } else {
                std::uint64_t u;
                std::memcpy(&u, b, 8);
                if (swap) u = __builtin_bswap64(u);
                finite = (u & 0x7ff0000000000000ull) != 0x7ff0000000000000ull;
            }
            if (!finite) values[static_cast<std::size_t>(i + k)] = std::numeric_limits<float>::quiet_NaN();
        }
        i += count;
    }
}

// MetaImage header fields ITK's MetaIO mishandles without an exception:
// NDims of 0 or less loops forever, a file pattern with step 0 loops
// forever printing errors, ASCII data (BinaryData = False) crashes the
// process (ITK 5.2/5.3), and a LIST or pattern naming missing files, an empty
// ElementDataFile or a HeaderSize past the end of the data leave voxels
// unread, which it reports only as a warning. Checked before MetaIO reads
// the header. (The data size of LOCAL and single-file data is checked after,
// by checkMetaImageSize, which needs the element size.)
void checkMetaImageHeader(const std::string& file) {
    auto fail = [&](const std::string& what) { throw Error(file + ": " + what); };
    auto trim = MetaHeader::trim;
    const MetaHeader header(file);
    long long ndims = 0;
    if (const std::string* value = header.get("NDims")) {
        std::istringstream v(*value);
        if (!(v >> ndims) || ndims < 1 || ndims > 8)
            fail("the MetaImage header says NDims = " + *value +
                 "; it must be the number of image dimensions (3 for a volume). Fix the header and retry.");
    }
    std::vector<long long> dims;
    if (const std::string* value = header.get("DimSize")) {
        std::istringstream v(*value);
        for (double d; v >> d;) dims.push_back(d >= 1 && d < 9e18 && d == std::floor(d) ? static_cast<long long>(d) : 0);
    }
    // MetaIO: binary when the value starts with T, t or 1
    const std::string* binaryValue = header.get("BinaryData");
    const bool binary = !binaryValue || (!binaryValue->empty() && ((*binaryValue)[0] == 'T' || (*binaryValue)[0] == 't' ||
                                                                   (*binaryValue)[0] == '1'));
    long long headerSize = 0;
    if (const std::string* value = header.get("HeaderSize")) std::istringstream(*value) >> headerSize;
    const std::string& dataFile = header.dataFile;
    std::ifstream in(file, std::ios::binary);  // for the LIST names after the header
    in.seekg(static_cast<std::streamoff>(header.dataStart));
    std::string line;
    if (!header.hasDataFile) return;  // not a MetaImage header as far as this check goes: MetaIO judges it
    if (ndims >= 1 && (static_cast<long long>(dims.size()) < ndims ||
                       std::any_of(dims.begin(), dims.begin() + ndims, [](long long d) { return d < 1; })))
        fail("the MetaImage header's DimSize does not give " + std::to_string(ndims) +
             " positive sizes; fix the header and retry.");
    if (!binary)
        fail("ASCII MetaImage data (BinaryData = False) is not supported: ITK's reader fails on it. Save the image "
             "with binary data (e.g. SimpleITK or 3D Slicer) and retry.");
    if (dataFile.empty())
        fail("the MetaImage header's ElementDataFile is empty; it must be LOCAL, LIST or the data file's name.");
    const std::filesystem::path dir = std::filesystem::path(file).parent_path();
    auto requireFile = [&](const std::string& name) {
        std::error_code ec;
        if (!std::filesystem::is_regular_file(dir / name, ec))
            fail("its voxel data file '" + (dir / name).string() +
                 "' is missing; keep the header and its data files together.");
    };
    const long long slices = ndims >= 1 && static_cast<long long>(dims.size()) >= ndims ? dims[ndims - 1] : 0;
    if (dataFile.rfind("LIST", 0) == 0) {
        // As MetaIO: "LIST nD" names files of n dimensions (default NDims-1),
        // one per index of the dimensions above; a last name without a line
        // end is not read.
        long long fileDim = ndims - 1;
        {
            std::istringstream w(dataFile.substr(4));
            double d = 0;
            if (w >> d && d >= 1 && d <= double(ndims)) fileDim = static_cast<long long>(d);
        }
        long long files = 1;
        for (long long a = fileDim; a < ndims && a < static_cast<long long>(dims.size()); ++a)
            files = std::min<long long>(files * std::max<long long>(dims[static_cast<std::size_t>(a)], 1), 1LL << 40);
        long long listed = 0;
        while (listed < files && std::getline(in, line)) {
            if (in.eof()) break;  // no line end: MetaIO stops before it
            const std::string name = trim(line);
            if (name.empty()) continue;
            requireFile(name);
            ++listed;
        }
        if (listed < files)
            fail("the MetaImage header lists " + std::to_string(listed) + " data file(s) (each on its own line) for " +
                 std::to_string(files) + " needed; every slice needs its file.");
    } else if (dataFile.find('%') != std::string::npos) {
        // MetaIO's reading of "pattern [first [last [step]]]": first 1, last
        // first + slices - 1, step (last - first) / slices with three words;
        // it loops for ever on a step of 0 and reads nothing for a negative one.
        std::istringstream v(dataFile);
        std::string pattern;
        v >> pattern;
        std::vector<double> words;
        for (double d; v >> d;) words.push_back(d);
        for (double d : words)
            if (!(std::fabs(d) < 1e9)) fail("the MetaImage file pattern '" + dataFile + "' has a number out of range; fix the header.");
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
        const auto percent = pattern.find('%');
        std::size_t at = percent + 1;
        while (at < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[at]))) ++at;
        if (at >= pattern.size() || (pattern[at] != 'd' && pattern[at] != 'i') ||
            pattern.find('%', at) != std::string::npos || pattern.size() > 1000)
            fail("the MetaImage file pattern '" + pattern + "' must hold one integer field such as %03d; fix the header.");
        if (step <= 0 || last < first)
            fail("the MetaImage file pattern '" + dataFile + "' steps by " + std::to_string(step) + " from " +
                 std::to_string(first) + " to " + std::to_string(last) +
                 ", which names no file or never ends; write the pattern as 'name first last step' with a step "
                 "of 1 or more and fix the header.");
        if ((last - first) / step + 1 < slices)
            fail("the MetaImage file pattern '" + dataFile + "' names " + std::to_string((last - first) / step + 1) +
                 " file(s) for " + std::to_string(slices) + " slices; every slice needs its file.");
        for (long long i = first, k = 0; k < slices; i += step, ++k) {
            char name[4096];
            std::snprintf(name, sizeof name, pattern.c_str(), static_cast<int>(i));
            requireFile(name);
        }
    } else if (headerSize > 0) {
        const bool local = dataFile == "LOCAL" || dataFile == "Local" || dataFile == "local";
        const std::filesystem::path data = local ? std::filesystem::path(file) : dir / dataFile;
        std::error_code ec;
        const auto have = std::filesystem::file_size(data, ec);
        if (!ec && static_cast<std::uint64_t>(headerSize) >= have)
            fail("the MetaImage header's HeaderSize (" + std::to_string(headerSize) + " bytes) is past the end of '" +
                 data.string() + "' (" + std::to_string(have) + " bytes); fix the header.");
    }
}

}  // namespace

// libtiff's messages while checkTiffLayout runs (its handlers are
// process-wide; scans are loaded on one thread).
std::vector<std::string>* gTiffMessages = nullptr;

void keepTiffMessage(const char* module, const char* fmt, va_list ap, bool warning) {
    char text[512];
    std::vsnprintf(text, sizeof text, fmt, ap);
    const std::string m = std::string(module ? module : "libtiff") + ": " + text;
    // Warnings are mostly about tags libtiff does not know (GeoTIFF, vendors'
    // own); a warning that a tag could not be read means the file ends early.
    if (gTiffMessages && (!warning || m.find("IO error") != std::string::npos)) gTiffMessages->push_back(m);
}
extern "C" void tiffError(const char* module, const char* fmt, va_list ap) { keepTiffMessage(module, fmt, ap, false); }
extern "C" void tiffWarning(const char* module, const char* fmt, va_list ap) { keepTiffMessage(module, fmt, ap, true); }

// A TIFF file cut short lost its last pages without a word: ITK reads the
// pages libtiff can find (libtiff only prints "Failed to read directory"),
// so a multi-page scan cut at 50% or 90% was meshed with fewer slices, and
// one cut at 10% ended in an Otsu message about constant voxels (the
// corrupted-input survey). Before ITK reads it, libtiff walks every page's
// directory here and each strip or tile must end inside the file; any
// libtiff error on the way (or a tag it could not read) refuses the file.
void checkTiffLayout(const std::string& file) {
    std::vector<std::string> messages;
    gTiffMessages = &messages;
    const TIFFErrorHandler oldError = TIFFSetErrorHandler(tiffError);
    const TIFFErrorHandler oldWarning = TIFFSetWarningHandler(tiffWarning);
    struct Restore {
        TIFFErrorHandler e, w;
        ~Restore() {
            TIFFSetErrorHandler(e);
            TIFFSetWarningHandler(w);
            gTiffMessages = nullptr;
        }
    } restore{oldError, oldWarning};
    std::error_code ec;
    const std::uint64_t size = std::filesystem::file_size(file, ec);
    if (ec) return;
    TIFF* tif = TIFFOpen(file.c_str(), "r");
    if (!tif) return;  // ITK says what it makes of a file libtiff cannot open
    std::string problem;
    int page = 0;
    do {
        ++page;
        const bool tiled = TIFFIsTiled(tif);
        const std::uint32_t pieces = tiled ? TIFFNumberOfTiles(tif) : TIFFNumberOfStrips(tif);
        for (std::uint32_t i = 0; i < pieces && problem.empty(); ++i) {
            const std::uint64_t offset = TIFFGetStrileOffset(tif, i), bytes = TIFFGetStrileByteCount(tif, i);
            if (offset > size || bytes > size - offset)
                problem = "page " + std::to_string(page) + "'s " + (tiled ? "tile " : "strip ") + std::to_string(i) +
                          " ends at byte " + std::to_string(offset + bytes) + " of a file of " + std::to_string(size);
        }
    } while (problem.empty() && messages.empty() && TIFFReadDirectory(tif));
    TIFFClose(tif);
    if (problem.empty() && !messages.empty()) problem = boundedMessage(messages.front(), 500);
    if (!problem.empty())
        throw Error(file + ": the TIFF file is damaged or truncated (" + problem + "); export it again.");
}

// Keeps GDCM's warnings and errors (process-wide streams; scans are loaded
// on one thread) off the console while it lives: where they matter, isohex's
// own message says what was wrong.
class QuietGdcm {
public:
    QuietGdcm() : warnings_(gdcm::Trace::GetWarningStream()), errors_(gdcm::Trace::GetErrorStream()) {
        gdcm::Trace::SetWarningStream(sink_);
        gdcm::Trace::SetErrorStream(sink_);
    }
    ~QuietGdcm() {
        gdcm::Trace::SetWarningStream(warnings_);
        gdcm::Trace::SetErrorStream(errors_);
    }
    bool said(const std::string& text) const { return sink_.str().find(text) != std::string::npos; }
    QuietGdcm(const QuietGdcm&) = delete;
    QuietGdcm& operator=(const QuietGdcm&) = delete;

private:
    std::ostringstream sink_;
    std::ostream& warnings_;
    std::ostream& errors_;
};

// A DICOM file cut short was read in part: GDCM keeps the Pixel Data's
// declared length, pads what is missing (it only prints "Incomplete Pixel
// Data found" to the console) and ITK meshed the padding. GDCM gives where
// the Pixel Data's value starts in the file (reading up to it with the value
// skipped) and its declared length (a full read); the value must end inside
// the file. Only Pixel Data is checked: GDCM's sums over a whole data set
// are of the file as it would write it again (a preamble it adds, VRs it
// fixes), which is not the file on disk. A deflated data set is exempt (its
// positions are in the inflated stream; one cut short fails GDCM's read).
//
// Returns what is wrong, or nothing; `full` has read the whole file, and
// `quiet` has kept GDCM's warnings of that read alone.
std::string dicomPixelDataCut(const std::string& file, const gdcm::Reader& full, const QuietGdcm& quiet) {
    std::error_code ec;
    const std::uint64_t size = std::filesystem::file_size(file, ec);
    if (ec || full.GetFile().GetHeader().GetDataSetTransferSyntax().IsEncoded()) return {};
    const gdcm::Tag pixelData(0x7fe0, 0x0010);
    const gdcm::DataSet& ds = full.GetFile().GetDataSet();
    if (!ds.FindDataElement(pixelData)) return {};
    const gdcm::DataElement& pd = ds.GetDataElement(pixelData);
    std::uint64_t length = 0;
    if (!pd.GetVL().IsUndefined()) length = std::uint64_t(pd.GetVL());
    else if (const gdcm::SequenceOfFragments* f = pd.GetSequenceOfFragments()) length = std::uint64_t(f->ComputeLength());
    else return {};
    gdcm::Reader upTo;
    upTo.SetFileName(file.c_str());
    if (!upTo.ReadUpToTag(pixelData, {pixelData})) return {};
    const std::uint64_t start = upTo.GetStreamCurrentPosition();
    // A read that ran to the end of the file did not stop at the Pixel Data
    // (GDCM's full read copes with a data set in another VR than the meta
    // header says, this one does not); then only GDCM's own warning tells.
    const bool cut = start < size ? length > size - start : quiet.said("Incomplete Pixel Data");
    if (!cut) return {};
    return file + ": the DICOM file is truncated (its pixel data starts at byte " + std::to_string(start) +
           " and declares " + std::to_string(length) + " bytes, the file has " + std::to_string(size) +
           "); copy or export it again.";
}

const char* const kDicomUnreadable =
    ": the DICOM file is damaged or truncated (GDCM cannot read its data set to the end); copy or export it again.";

// The check above for one DICOM file read on its own (a multi-frame file).
void checkDicomLength(const std::string& file) {
    QuietGdcm quiet;  // its "Incomplete Pixel Data" warning would only repeat ours
    gdcm::Reader full;
    full.SetFileName(file.c_str());
    if (!full.Read()) throw Error(file + kDicomUnreadable);  // ITK read a deflated data set cut short
    const std::string cut = dicomPixelDataCut(file, full, quiet);
    if (!cut.empty()) throw Error(cut);
}

// The numbers of a DICOM decimal-string value (backslash-separated); empty if any
// is not a number.
std::vector<double> dicomNumbers(const char* value) {
    std::vector<double> out;
    if (!value) return out;
    std::istringstream in(value);
    in.imbue(std::locale::classic());
    std::string piece;
    while (std::getline(in, piece, '\\')) {
        std::istringstream one(piece);
        one.imbue(std::locale::classic());
        double x = 0;
        if (!(one >> x) || !std::isfinite(x)) return {};
        out.push_back(x);
    }
    return out;
}

// ITK stacks a series' slices at one spacing (from the first and last
// positions), so a slice missing from the folder (a transfer cut short, or a
// file GDCM could not parse and left out of the series) or a protocol with
// variable spacing was meshed with every slice after the gap in the wrong
// place, without a word. The slices' Image Position (Patient) along their
// normal (from Image Orientation (Patient)) must step evenly, within 10% of
// the median step plus 0.1 (mm; positions are often rounded to 0.1 mm).
// Slices without those tags are left to ITK.
void checkSliceSpacing(const std::string& folder, const std::vector<std::string>& files) {
    const gdcm::Tag position(0x0020, 0x0032), orientation(0x0020, 0x0037);
    gdcm::Scanner scanner;
    scanner.AddTag(position);
    scanner.AddTag(orientation);
    {
        QuietGdcm quiet;
        if (!scanner.Scan(files)) return;
    }
    const std::vector<double> iop = dicomNumbers(scanner.GetValue(files.front().c_str(), orientation));
    if (iop.size() != 6) return;
    using V = itk::Vector<double, 3>;
    V normal = itk::CrossProduct(V(std::array<double, 3>{iop[0], iop[1], iop[2]}.data()),
                                 V(std::array<double, 3>{iop[3], iop[4], iop[5]}.data()));
    if (!(normal.GetNorm() > 0.5)) return;
    normal.Normalize();
    std::vector<double> along;
    for (const auto& f : files) {
        const std::vector<double> p = dicomNumbers(scanner.GetValue(f.c_str(), position));
        if (p.size() != 3) return;
        along.push_back(normal[0] * p[0] + normal[1] * p[1] + normal[2] * p[2]);
    }
    std::vector<double> steps;
    for (std::size_t i = 1; i < along.size(); ++i) steps.push_back(along[i] - along[i - 1]);
    // Slices at one position, or out of order (GDCM could not sort them, e.g.
    // two phases in one series): not a question of spacing; left as before.
    const bool up = steps.front() > 0;
    for (double step : steps)
        if (step == 0 || (step > 0) != up) return;
    std::vector<double> sorted = steps;
    std::nth_element(sorted.begin(), sorted.begin() + (sorted.size() - 1) / 2, sorted.end());
    const double median = sorted[(sorted.size() - 1) / 2];  // the lower middle of an even count
    // Positions are often written to 0.1 mm, so 0.1 on top of 10%.
    const double tolerance = 0.1 * std::abs(median) + 0.1;
    std::size_t shortest = 0, longest = 0, uneven = 0;
    for (std::size_t i = 0; i < steps.size(); ++i) {
        if (std::abs(steps[i] - median) > tolerance) ++uneven;
        if (std::abs(steps[i]) < std::abs(steps[shortest])) shortest = i;
        if (std::abs(steps[i]) > std::abs(steps[longest])) longest = i;
    }
    if (uneven == 0) return;
    auto between = [&](std::size_t i) {
        return std::filesystem::path(files[i]).filename().string() + " and " +
               std::filesystem::path(files[i + 1]).filename().string();
    };
    std::ostringstream m;
    m.precision(6);
    m << folder << ": the DICOM slices are not evenly spaced: along the slice normal the step between slices "
      << "goes from " << std::abs(steps[shortest]) << " (" << between(shortest) << ") to " << std::abs(steps[longest])
      << " (" << between(longest) << "); " << uneven << " of " << steps.size()
      << " steps differ from the median step, " << std::abs(median) << ", by more than 10% (+0.1). ";
    if (std::abs(steps[longest]) > 1.5 * std::abs(median))
        m << "A slice is probably missing between " << between(longest)
          << " (an incomplete transfer, or a damaged file GDCM left out of the series); copy or export the "
             "series again.";
    else
        m << "isohex needs one slice spacing; resample the series to even spacing first.";
    throw Error(m.str());
}

RawVolume readImageFileItk(const std::filesystem::path& path, const LoadOptions& options) {
    const std::string file = path.string();
    itk::ImageIOBase::Pointer io;
    {
        QuietGdcm quiet;  // the DICOM probe reads a file cut short and warns; checkDicomLength says why
        io = itk::ImageIOFactory::CreateImageIO(file.c_str(), itk::IOFileModeEnum::ReadMode);
    }
    if (!io) {
        // A gzip stream whose name does not say so (.nii instead of .nii.gz):
        // the readers pick gzip by the extension.
        unsigned char magic[2] = {0, 0};
        if (std::FILE* f = std::fopen(file.c_str(), "rb")) {
            const std::size_t n = std::fread(magic, 1, 2, f);
            std::fclose(f);
            if (n == 2 && magic[0] == 0x1f && magic[1] == 0x8b && path.extension() != ".gz")
                throw Error(file + ": the file is gzip-compressed but its name does not end in .gz; rename it to " +
                            path.filename().string() + ".gz or decompress it with gunzip.");
        }
        throw Error(file + ": not a readable image: no reader recognises its header (damaged "
                    "file, or a format other than NIfTI, NRRD, MetaImage, TIFF, DICOM, OpenVDB). "
                    "Check that the file is complete and its extension matches its content.");
    }
    io->SetFileName(file);
    {
        std::string lower = path.filename().string();
        for (auto& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        auto endsWith = [&](const std::string& e) {
            return lower.size() >= e.size() && lower.compare(lower.size() - e.size(), e.size(), e) == 0;
        };
        if (endsWith(".mha") || endsWith(".mhd")) checkMetaImageHeader(file);
        if (endsWith(".nii") || endsWith(".nii.gz")) checkNiftiOrientation(file);
        if (endsWith(".tif") || endsWith(".tiff")) checkTiffLayout(file);
    }
    if (std::string(io->GetNameOfClass()) == "GDCMImageIO") checkDicomLength(file);
    try {
        io->ReadImageInformation();
    } catch (const itk::ExceptionObject& e) {
        throw Error(file + ": the " + formatName(*io) + " header cannot be read (" + describe(e) +
                    "). The file is damaged or not a " + formatName(*io) + " file; re-export it.");
    }

    RawHeader header;
    header.dimensions = static_cast<int>(io->GetNumberOfDimensions());
    header.components = static_cast<int>(io->GetNumberOfComponents());
    header.bytesPerComponent = static_cast<int>(io->GetComponentSize());
    for (int a = 0; a < std::min(header.dimensions, 4); ++a) header.size[a] = io->GetDimensions(a);

    const auto pixel = io->GetPixelType();
    const auto component = io->GetComponentType();
    if (pixel == itk::IOPixelEnum::COMPLEX || component == itk::IOComponentEnum::UNKNOWNCOMPONENTTYPE) {
        throw Error(file + ": unsupported pixel type '" +
                    itk::ImageIOBase::GetPixelTypeAsString(pixel) + "' of " +
                    itk::ImageIOBase::GetComponentTypeAsString(component) +
                    "; isohex reads real-valued scalar images (integer or float). Convert it to "
                    "a scalar image first (e.g. the magnitude of complex data).");
    }
    if (header.dimensions < 3 || header.dimensions > 4) {
        std::ostringstream m;
        m << file << ": a " << header.dimensions
          << "-D image; isohex needs a 3-D volume (or a 4-D image with the volume index option).";
        if (header.dimensions == 2) m << " For a stack of 2-D slices pass the folder holding them.";
        throw Error(m.str());
    }
    const std::int64_t frames = header.size[3];
    const std::int64_t choices = frames * header.components;
    if (choices > 1) {
        std::ostringstream what;
        if (frames > 1 && header.components > 1)
            what << frames << " volumes of " << header.components << " components each";
        else if (frames > 1)
            what << "a 4-D image of " << frames << " volumes";
        else
            what << header.components << " components per voxel ("
                 << itk::ImageIOBase::GetPixelTypeAsString(pixel) << ")";
        if (options.volumeIndex < 0) {
            throw Error(file + ": holds " + what.str() +
                        "; isohex meshes one scalar volume. Choose one with the volume index "
                        "option (0.." + std::to_string(choices - 1) + ").");
        }
        if (options.volumeIndex >= choices) {
            throw Error(file + ": volume index " + std::to_string(options.volumeIndex) +
                        " is out of range; the file holds " + what.str() + ", so use 0.." +
                        std::to_string(choices - 1) + ".");
        }
    } else if (options.volumeIndex > 0) {
        throw Error(file + ": volume index " + std::to_string(options.volumeIndex) +
                    " does not exist: the file holds one scalar volume (index 0). Leave the option out.");
    }
    checkMemoryBudget(file, header, options.maxMemoryMB);
    {
        const auto bytes = static_cast<std::uint64_t>(io->GetImageSizeInBytes());
        std::string name = path.filename().string();
        for (auto& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        auto endsWith = [&](const char* e) {
            const std::size_t n = std::strlen(e);
            return name.size() >= n && name.compare(name.size() - n, n, e) == 0;
        };
        if (endsWith(".nii") || endsWith(".nii.gz")) checkNiftiDataSize(file, bytes, endsWith(".nii.gz"));
        if (endsWith(".mha") || endsWith(".mhd")) checkMetaImageSize(file, bytes);
    }

    auto reader = itk::ImageFileReader<VectorImage4>::New();
    reader->SetImageIO(io);
    reader->SetFileName(file);
    if (options.progress) options.progress("read", 0.0);
    try {
        reader->Update();
    } catch (const itk::ExceptionObject& e) {
        throw Error(file + ": the voxel data cannot be read (" + describe(e) +
                    "). The file is probably truncated or damaged; copy or export it again.");
    } catch (const std::bad_alloc&) {
        throw Error(file + ": out of memory while reading the voxel data; use a machine with "
                    "more memory or crop/downsample the scan first.");
    }
    if (options.progress) options.progress("read", 1.0);
    VectorImage4::Pointer image = reader->GetOutput();
    const auto size = image->GetLargestPossibleRegion().GetSize();

    RawVolume raw;
    raw.format = formatName(*io);
    raw.pixelType = componentName(component);
    for (int a = 0; a < 3; ++a) raw.dims[a] = static_cast<std::int64_t>(size[a]);
    copyGeometry(*image, raw);

    const std::int64_t n = raw.count();
    const int comps = static_cast<int>(image->GetNumberOfComponentsPerPixel());
    const std::int64_t pick = std::max(options.volumeIndex, 0);
    const std::int64_t frame = choices > 1 ? pick / comps : 0;
    const int comp = choices > 1 ? static_cast<int>(pick % comps) : 0;
    const float* buffer = image->GetBufferPointer();
    raw.values.resize(static_cast<std::size_t>(n));
    const float* base = buffer + frame * n * comps + comp;
    if (comps == 1) {
        std::copy(base, base + n, raw.values.begin());
    } else {
        for (std::int64_t i = 0; i < n; ++i) raw.values[i] = base[i * comps];
    }
    image = nullptr;
    reader = nullptr;
    {
        std::string lower = path.filename().string();
        for (auto& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        const bool nifti = (lower.size() > 4 && lower.compare(lower.size() - 4, 4, ".nii") == 0) ||
                           (lower.size() > 7 && lower.compare(lower.size() - 7, 7, ".nii.gz") == 0);
        // (Not for label maps: a float label map padded with NaN, as
        // resampling with NaN fill writes, keeps NaN as background 0.)
        if (nifti && !options.labels)
            restoreNiftiNonFinite(file, raw.values, frame, std::max<std::int64_t>(frames, 1), comp);
    }

    // TIFF carries no usable physical geometry; the caller supplies it.
    if (raw.format == "TIFF") {
        raw.spacing = options.sliceSpacing;
        raw.origin = options.sliceOrigin;
        raw.direction = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    }
    checkGeometry(raw, file);
    if (options.labels) convertToLabels(raw, file, isIntegerComponent(component));
    return raw;
}

// What GDCM makes of one file of a DICOM folder, read before its series scan.
struct DicomFileScan {
    bool marked = false;  // "DICM" after the 128-byte preamble
    bool named = false;   // not marked, but named .dcm or .dicom
    bool readable = false;
    bool imageWithoutPixels = false;  // an image storage class, but no Pixel Data
    std::string cut;                  // dicomPixelDataCut's finding
};

// Reads every file of the folder with GDCM before ITK's series scan does, one
// at a time and named through `reading` first: Debian's GDCM stops the process
// on an assertion for a file cut inside its header, and the scan reads the
// whole folder in one call, so the crash report could only name the folder.
std::map<std::filesystem::path, DicomFileScan> scanDicomFolder(const std::filesystem::path& dir,
                                                             const LoadOptions& options) {
    std::map<std::filesystem::path, DicomFileScan> out;
    std::error_code ec;
    std::vector<std::filesystem::path> files;
    for (const auto& entry : std::filesystem::directory_iterator(dir, ec))
        if (entry.is_regular_file(ec)) files.push_back(entry.path().lexically_normal());
    std::sort(files.begin(), files.end());
    for (const auto& file : files) {
        if (file.filename().string().rfind("._", 0) == 0) continue;  // macOS AppleDouble side files
        DicomFileScan& scan = out[file];
        char mark[4] = {0, 0, 0, 0};
        {
            std::ifstream in(file, std::ios::binary);
            scan.marked = in.seekg(128) && in.read(mark, 4) && std::memcmp(mark, "DICM", 4) == 0;
        }
        if (!scan.marked) {  // cut before the mark, or older files without a preamble
            std::string ext = file.extension().string();
            for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
            scan.named = ext == ".dcm" || ext == ".dicom";
        }
        if (options.reading) options.reading(file.string());
        QuietGdcm quiet;  // per file: dicomPixelDataCut looks for this read's warning
        gdcm::Reader reader;
        reader.SetFileName(file.c_str());
        scan.readable = reader.Read();
        if (!scan.readable) continue;
        const gdcm::DataSet& ds = reader.GetFile().GetDataSet();
        gdcm::MediaStorage storage;
        storage.SetFromFile(reader.GetFile());
        scan.imageWithoutPixels = gdcm::MediaStorage::IsImage(storage) && !ds.FindDataElement(gdcm::Tag(0x7fe0, 0x0010));
        scan.cut = dicomPixelDataCut(file.string(), reader, quiet);
    }
    if (options.reading) options.reading(dir.string());
    return out;
}

// GDCM's series scan leaves out, without a word, a file whose data set it
// cannot parse (a deflated file cut short, a damaged header) or that has no
// image left (a file cut before its Pixel Data), so a damaged first or last
// slice made the volume a slice shorter. A file no series lists is refused by
// name if it says it is DICOM (its mark, or a .dcm name) and GDCM cannot read
// it, or if it is of an image storage class but has no Pixel Data. Other
// files no series lists (a DICOMDIR, a report, notes, macOS's "._" side
// files) are left alone.
void checkUnlistedDicomFiles(const std::map<std::filesystem::path, DicomFileScan>& scans,
                             const std::set<std::filesystem::path>& listed) {
    for (const auto& [file, scan] : scans) {
        if (listed.count(file)) continue;
        if ((scan.marked || scan.named) && !scan.readable)
            throw Error(file.string() + ": this DICOM file in the series folder is damaged or truncated (GDCM "
                        "cannot read its data set), so it was left out of the series; copy or export the series "
                        "again, or remove the file if it is not part of the scan.");
        if (scan.marked && scan.imageWithoutPixels)
            throw Error(file.string() + ": this DICOM image file in the series folder has no pixel data (it is "
                        "probably truncated), so it was left out of the series; copy or export the series again, "
                        "or remove the file if it is not part of the scan.");
    }
}

RawVolume readDicomFolderItk(const std::filesystem::path& dir, const LoadOptions& options) {
    const std::string folder = dir.string();
    auto names = itk::GDCMSeriesFileNames::New();
    // Series details split series that share a UID but differ in orientation or
    // size; it must be set before the directory is scanned.
    names->SetUseSeriesDetails(true);
    names->SetGlobalWarningDisplay(false);
    std::vector<std::string> ids;
    const auto scans = scanDicomFolder(dir, options);
    try {
        QuietGdcm quiet;  // about files in the folder that are not DICOM
        names->SetDirectory(folder);
        ids = names->GetSeriesUIDs();
    } catch (const itk::ExceptionObject& e) {
        throw Error(folder + ": scanning for DICOM files failed (" + describe(e) + ").");
    }
    if (ids.empty()) {
        throw Error(folder + ": no DICOM series, .exr slices or .tif slices found in this folder. "
                    "Pass a folder of DICOM files (one series), a folder of slices, or an image file.");
    }
    struct Series {
        std::string id;
        std::vector<std::string> files;
    };
    std::vector<Series> series;
    for (const auto& id : ids) series.push_back({id, names->GetFileNames(id)});

    auto listing = [&] {
        std::ostringstream m;
        for (const auto& s : series) m << "\n  " << s.id << "  (" << s.files.size() << " slices)";
        return m.str();
    };
    const Series* chosen = nullptr;
    if (!options.seriesUid.empty()) {
        // With series details the ids are the SeriesInstanceUID followed by
        // more fields; accept the plain UID as a prefix.
        std::vector<const Series*> hits;
        for (const auto& s : series)
            if (s.id == options.seriesUid || s.id.rfind(options.seriesUid, 0) == 0) hits.push_back(&s);
        if (hits.size() != 1) {
            throw Error(folder + ": series '" + options.seriesUid + "' " +
                        (hits.empty() ? "is not in this folder" : "matches several series") +
                        ". The folder holds:" + listing() + "\nPass one of these as the series UID.");
        }
        chosen = hits.front();
    } else {
        std::size_t most = 0;
        for (const auto& s : series) most = std::max(most, s.files.size());
        std::vector<const Series*> largest;
        for (const auto& s : series)
            if (s.files.size() == most) largest.push_back(&s);
        if (largest.size() > 1) {
            throw Error(folder + ": holds " + std::to_string(series.size()) +
                        " DICOM series and several have the most slices (" + std::to_string(most) +
                        "), so which to mesh is ambiguous:" + listing() +
                        "\nChoose one with the series UID option.");
        }
        chosen = largest.front();
    }
    {
        std::set<std::filesystem::path> listed;
        for (const auto& sr : series)
            for (const auto& f : sr.files) listed.insert(std::filesystem::path(f).lexically_normal());
        checkUnlistedDicomFiles(scans, listed);
    }
    // Before ITK reads any of them (its header read decodes the first slice).
    if (chosen->files.size() > 1) {
        for (const auto& f : chosen->files) {
            const auto it = scans.find(std::filesystem::path(f).lexically_normal());
            if (it == scans.end()) {
                checkDicomLength(f);  // not expected: the scan read the same folder
            } else {
                if (!it->second.readable) throw Error(f + kDicomUnreadable);
                if (!it->second.cut.empty()) throw Error(it->second.cut);
            }
        }
        checkSliceSpacing(folder, chosen->files);
    }
    if (chosen->files.size() == 1) {
        // One file can hold the whole volume: a multi-frame DICOM (enhanced
        // CT or MR, and what ITK writes for a 3-D image). It is read as the
        // image file it is; the folder used to call it "a single slice".
        auto probe = itk::GDCMImageIO::New();
        bool frames = false;
        try {
            QuietGdcm quiet;  // readImageFileItk checks the file
            probe->SetFileName(chosen->files.front());
            probe->ReadImageInformation();
            frames = probe->GetNumberOfDimensions() >= 3 && probe->GetDimensions(2) > 1;
        } catch (const itk::ExceptionObject&) {
            // unreadable: the header check below says so
        }
        if (frames) return readImageFileItk(chosen->files.front(), options);
    }
    if (chosen->files.size() < 2) {
        throw Error(folder + ": DICOM series " + chosen->id + " has a single slice; isohex needs "
                    "a 3-D volume (a series of at least two slices, or one multi-frame file).");
    }

    auto io = itk::GDCMImageIO::New();
    try {
        io->SetFileName(chosen->files.front());
        io->ReadImageInformation();
    } catch (const itk::ExceptionObject& e) {
        throw Error(chosen->files.front() + ": the DICOM header cannot be read (" + describe(e) +
                    "); the file is damaged, remove or replace it.");
    }
    if (io->GetNumberOfComponents() != 1) {
        throw Error(chosen->files.front() + ": DICOM images with " +
                    std::to_string(io->GetNumberOfComponents()) +
                    " components per pixel (colour) are not supported; isohex needs greyscale.");
    }
    RawHeader header;
    header.size = {static_cast<std::int64_t>(io->GetDimensions(0)),
                   static_cast<std::int64_t>(io->GetDimensions(1)),
                   static_cast<std::int64_t>(chosen->files.size()), 1};
    header.bytesPerComponent = 4;  // read as float after rescaling
    checkMemoryBudget(folder, header, options.maxMemoryMB);

    auto reader = itk::ImageSeriesReader<FloatImage3>::New();
    reader->SetImageIO(io);
    reader->SetFileNames(chosen->files);  // ordered along the slice normal
    if (options.progress) options.progress("read", 0.0);
    try {
        reader->Update();  // GDCMImageIO applies rescale slope and intercept
    } catch (const itk::ExceptionObject& e) {
        throw Error(folder + ": reading DICOM series " + chosen->id + " failed (" + describe(e) +
                    "). A slice is probably truncated or damaged.");
    }
    if (options.progress) options.progress("read", 1.0);
    FloatImage3::Pointer image = reader->GetOutput();
    RawVolume raw;
    raw.format = "DICOM";
    raw.pixelType = componentName(io->GetInternalComponentType());
    std::string uid;
    if (itk::ExposeMetaData<std::string>(io->GetMetaDataDictionary(), "0020|000e", uid)) {
        while (!uid.empty() && (uid.back() == ' ' || uid.back() == '\0')) uid.pop_back();
        raw.seriesUid = uid;
    } else {
        raw.seriesUid = chosen->id;
    }
    const auto size = image->GetLargestPossibleRegion().GetSize();
    for (int a = 0; a < 3; ++a) raw.dims[a] = static_cast<std::int64_t>(size[a]);
    copyGeometry(*image, raw);
    raw.values.assign(image->GetBufferPointer(), image->GetBufferPointer() + raw.count());
    image = nullptr;
    checkGeometry(raw, folder);
    if (options.labels) convertToLabels(raw, folder, true);
    return raw;
}

RawVolume readTiffSlicesItk(const std::vector<std::filesystem::path>& files,
                            const LoadOptions& options) {
    const std::string folder = files.front().parent_path().string();
    for (const auto& f : files) checkTiffLayout(f.string());
    auto io = itk::TIFFImageIO::New();
    io->SetFileName(files.front().string());
    try {
        io->ReadImageInformation();
    } catch (const itk::ExceptionObject& e) {
        throw Error(files.front().string() + ": the TIFF header cannot be read (" + describe(e) + ").");
    }
    if (io->GetNumberOfComponents() != 1) {
        throw Error(files.front().string() + ": TIFF slices with " +
                    std::to_string(io->GetNumberOfComponents()) +
                    " channels are not supported; save single-channel (greyscale) slices.");
    }
    RawHeader header;
    header.size = {static_cast<std::int64_t>(io->GetDimensions(0)),
                   static_cast<std::int64_t>(io->GetDimensions(1)),
                   static_cast<std::int64_t>(files.size()), 1};
    header.bytesPerComponent = 4;
    checkMemoryBudget(folder, header, options.maxMemoryMB);

    auto reader = itk::ImageSeriesReader<FloatImage3>::New();
    reader->SetImageIO(io);
    std::vector<std::string> names;
    for (const auto& f : files) names.push_back(f.string());
    reader->SetFileNames(names);
    try {
        reader->Update();
    } catch (const itk::ExceptionObject& e) {
        throw Error(folder + ": reading the TIFF slices failed (" + describe(e) +
                    "). Check that all slices have the same size and none is damaged.");
    }
    FloatImage3::Pointer image = reader->GetOutput();
    RawVolume raw;
    raw.format = "TIFF";
    raw.pixelType = componentName(io->GetComponentType());
    const auto size = image->GetLargestPossibleRegion().GetSize();
    for (int a = 0; a < 3; ++a) raw.dims[a] = static_cast<std::int64_t>(size[a]);
    raw.values.assign(image->GetBufferPointer(), image->GetBufferPointer() + raw.count());
    raw.spacing = options.sliceSpacing;
    raw.origin = options.sliceOrigin;
    checkGeometry(raw, folder);
    if (options.labels) convertToLabels(raw, folder, isIntegerComponent(io->GetComponentType()));
    return raw;
}

}  // namespace isohex::imaging::detail

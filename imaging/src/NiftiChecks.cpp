// NIfTI checks around the readers, ITK and libnifti2 (see FormatChecks.hpp). The header is read
// with gzread, which reads an uncompressed file as it is, so one path serves
// .nii and .nii.gz.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <sstream>
#include <type_traits>

#include <zlib.h>

#include "DataFilePlace.hpp"
#include "FormatChecks.hpp"

namespace isohex::imaging::detail {
namespace {

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

// Uncompressed bytes in a gzip file, reading it through to the end. A cut
// gzip stream ends early, which the NIfTI reader would zero-fill silently.
// Damaged compressed data (zlib's Z_DATA_ERROR: a bad CRC or length check,
// an invalid block) is refused here with its own message: ITK reads the
// voxels before the check bytes, so it would otherwise pass unnoticed or
// look like a truncation.
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

}  // namespace

int niftiVersion(const std::string& file) {
    const NiftiHeader h(file);
    return h.got < 4 || !h.known ? 0 : h.v1 ? 1 : 2;
}

int niftiIntegerBytes(const std::string& file) {
    const NiftiHeader h(file);
    if (h.got < 348 || !h.known || (!h.v1 && h.got < 540)) return 0;
    switch (h.field<std::int16_t>(h.v1 ? 70 : 12)) {
        case 2: case 256: return 1;       // uint8, int8
        case 4: case 512: return 2;       // int16, uint16
        case 8: case 768: return 4;       // int32, uint32
        case 1024: case 1280: return 8;   // int64, uint64
        default: return 0;
    }
}

bool niftiOneFileMagic(const std::string& file) {
    const NiftiHeader h(file);
    return h.got >= 348 && h.known && h.v1 && std::memcmp(h.bytes + 344, "n+1", 4) == 0;
}

// NIfTI's reader zero-fills missing voxel bytes with only a debug message, and
// reads the start of data longer than the header says as a whole volume, so
// check the size against the header ourselves: the file's size (for a pair,
// the .img's), or for a .nii.gz its uncompressed size (reading it through: a
// cut gzip stream ends early), against vox_offset plus the voxel bytes. A
// file cut right after its header is truncated too, not a volume of zeros.
void checkNiftiDataSize(const std::string& file, const std::string& dataFile, std::uint64_t dataBytes, bool gzipped) {
    const NiftiHeader h(file);
    if (h.got < (h.v1 ? 348 : 540) || !h.known) return;  // too short for a header; ITK has judged it already
    const double voxOffset = h.voxOffset();
    if (!gzipped && (h.compressed || !(voxOffset >= 0))) return;  // (a gzip stream named .nii: its file size says nothing)
    const double headerEnd = h.v1 ? 352.0 : 544.0;
    const bool pair = dataFile != file;
    const std::uint64_t need = std::uint64_t(gzipped ? std::max(voxOffset, headerEnd) : voxOffset) + dataBytes;
    const std::uint64_t have = gzipped ? gunzippedSize(file) : std::filesystem::file_size(dataFile);
    if (have < need) throwTruncated(pair ? dataFile : file, need, have, gzipped ? "uncompressed bytes" : "bytes");
    if (have > need)
        throw Error((pair ? dataFile : file) + ": holds " + std::to_string(have - need) +
                    " bytes more voxel data than the NIfTI header's dim and datatype account for (" +
                    std::to_string(dataBytes) + " bytes from byte " + std::to_string(std::uint64_t(voxOffset)) +
                    "): the header does not describe the data (dim too small, or the wrong datatype), so its "
                    "voxels would be read scrambled. Fix the header or export the file again.");
}

namespace {

// Bits per voxel of each NIfTI datatype, 0 for codes NIfTI does not define.
int niftiTypeBits(int datatype) {
    switch (datatype) {
        case 2: case 256: return 8;
        case 4: case 512: return 16;
        case 8: case 16: case 768: case 2304: return 32;
        case 128: return 24;
        case 32: case 64: case 1024: case 1280: return 64;
        case 1536: case 1792: return 128;
        case 2048: return 256;
        default: return 0;
    }
}

[[noreturn]] void refuseField(const std::string& file, const std::string& what) {
    throw Error(file + ": the NIfTI header's " + what + ". Fix the header or export the file again.");
}

// vox_offset: a number, and for a single file past the header (nifti1_io
// moves a smaller one to the end of the header without a word).
void checkVoxOffset(const std::string& file, const NiftiHeader& h, bool pair) {
    const double at = h.v1 ? double(h.field<float>(108)) : double(h.field<std::int64_t>(168));
    const double headerEnd = h.v1 ? 352.0 : 544.0;
    std::ostringstream value;
    value << at;
    if (!std::isfinite(at)) refuseField(file, "vox_offset (where the voxels start) is " + value.str() + ", not a number");
    if (at < 0) refuseField(file, "vox_offset (where the voxels start) is negative (" + value.str() + ")");
    if (!pair && at < headerEnd)
        refuseField(file, "vox_offset (where the voxels start) is " + value.str() + ", inside the " +
                              std::to_string(int(headerEnd)) + "-byte header; in a .nii file the voxels start at byte " +
                              std::to_string(int(headerEnd)) + " or later");
}

}  // namespace

// Header fields nifti1_io reads past without a word: a bitpix that is not
// the datatype's size (the voxels are read by datatype, so the header
// contradicts itself), vox_offset, and a zero pixdim where the spacing comes
// from pixdim (no sform), which it takes as 1 mm. The data file of a pair
// (.hdr with .img) must be a regular file; its absence is the .img's fault.
void checkNiftiHeaderFields(const std::string& file, const std::string& dataFile) {
    const bool pair = dataFile != file;
    if (pair) checkDataFilePlace(file, std::filesystem::path(dataFile).filename().string(), true);  // named by convention, not by the header
    const NiftiHeader h(file);
    if (h.got < 348 || !h.known || (!h.v1 && h.got < 540)) return;  // ITK judges short headers
    const int datatype = h.field<std::int16_t>(h.v1 ? 70 : 12), bitpix = h.field<std::int16_t>(h.v1 ? 72 : 14);
    if (const int bits = niftiTypeBits(datatype); bits > 0 && bitpix != bits)
        refuseField(file, "datatype (" + std::to_string(datatype) + ", " + std::to_string(bits) +
                              " bits per voxel) and bitpix (" + std::to_string(bitpix) +
                              ") disagree, so the voxels' size is unknown");
    checkVoxOffset(file, h, pair);
    const bool nifti = std::memcmp(h.bytes + (h.v1 ? 344 : 4), h.v1 ? (pair ? "ni1" : "n+1") : (pair ? "ni2" : "n+2"), 3) == 0;
    const int sform = !nifti ? 0 : h.v1 ? h.field<std::int16_t>(254) : h.field<std::int32_t>(348);
    const auto dims = h.v1 ? std::int64_t(h.field<std::int16_t>(40)) : h.field<std::int64_t>(16);
    for (int k = 1; k <= std::min<std::int64_t>(dims, 3) && sform <= 0; ++k)
        if (h.real(76 + 4 * k, 104 + 8 * k) == 0.0)
            refuseField(file, "pixdim[" + std::to_string(k) + "] (the voxel spacing along axis " +
                                  std::to_string(k - 1) + ") is 0 and no sform gives the spacing instead; "
                                  "nifti1_io would assume 1 mm without a word");
}

// NIfTI orientation fields that are not finite make ITK's reader abort the
// process (vnl's matrix code calls abort() on a NaN in srow_x, which ends a
// whole batch). Checked before
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

namespace {

// Calls onNonFinite(k) for each of the next n float voxels (`width` bytes
// each) of `gz` that is NaN or infinite, k counted from the first. False on a
// short read (the size checks report it) or when onNonFinite returns false.
template <class OnNonFinite>
bool scanNonFinite(gzFile gz, std::int64_t n, std::size_t width, bool swap, OnNonFinite onNonFinite) {
    std::vector<unsigned char> chunk(width * 65536);
    for (std::int64_t i = 0; i < n;) {
        const std::int64_t count = std::min<std::int64_t>(65536, n - i);
        const int want = static_cast<int>(count * static_cast<std::int64_t>(width));
        if (gzread(gz, chunk.data(), static_cast<unsigned>(want)) != want) return false;
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
            if (!finite && !onNonFinite(i + k)) return false;
        }
        i += count;
    }
    return true;
}

// The file's float voxel data opened at vox_offset plus `first` voxels, and
// the voxel width; null for headers that are not float NIfTI.
struct FloatVoxels {
    std::unique_ptr<std::remove_pointer_t<gzFile>, int (*)(gzFile)> gz{nullptr, gzclose};
    std::size_t width = 0;
    bool swap = false;
};

FloatVoxels openFloatVoxels(const std::string& file, const NiftiHeader& h, std::int64_t first) {
    FloatVoxels v;
    if (h.got < 348 || !h.known || (!h.v1 && h.got < 540)) return v;
    const auto dt = h.field<std::uint16_t>(h.v1 ? 70 : 12);
    if (dt != 16 && dt != 64) return v;  // only float32 and float64 voxels can be non-finite
    const double stored = h.voxOffset();
    if (!std::isfinite(stored)) return v;
    const double voxOffset = std::max(stored, h.v1 ? 352.0 : 544.0);
    v.width = dt == 16 ? 4 : 8;
    v.swap = h.swap;
    v.gz.reset(gzopen(file.c_str(), "rb"));
    if (v.gz && gzseek(v.gz.get(), static_cast<z_off_t>(voxOffset + double(first) * double(v.width)), SEEK_SET) < 0)
        v.gz.reset();
    return v;
}

}  // namespace

// nifti1_io (inside ITK's NIfTI reader) replaces NaN and infinite float
// voxels with 0, with only a debug message, so a NIfTI scan never reached
// isohex's NaN policy (refuse, or outside with --nan-as-outside) and was
// meshed with zeros in the holes. This reads the float voxels of the chosen
// volume (`frame` of `frames`, component `comp`) again and puts NaN back
// where the file has a non-finite value.
void restoreNiftiNonFinite(const std::string& file, std::vector<float>& values, std::int64_t frame,
                           std::int64_t frames, int comp) {
    const NiftiHeader h(file);
    const auto n = static_cast<std::int64_t>(values.size());
    // NIfTI order: x fastest, then y, z, t (frames), then the components.
    const FloatVoxels v = openFloatVoxels(file, h, (std::int64_t(comp) * frames + frame) * n);
    if (!v.gz) return;
    scanNonFinite(v.gz.get(), n, v.width, v.swap, [&](std::int64_t k) {
        values[static_cast<std::size_t>(k)] = std::numeric_limits<float>::quiet_NaN();
        return true;
    });
}

bool niftiHasNonFinite(const std::string& file) {
    const NiftiHeader h(file);
    if (!h.v1 || h.got < 348 || !h.known) return false;
    const auto rank = h.field<std::int16_t>(40);
    std::int64_t n = 1;
    for (int d = 1; d <= std::clamp<int>(rank, 0, 7); ++d) n *= std::max<std::int64_t>(h.field<std::int16_t>(40 + 2 * d), 1);
    const FloatVoxels v = openFloatVoxels(file, h, 0);
    if (!v.gz) return false;
    bool found = false;
    scanNonFinite(v.gz.get(), n, v.width, v.swap, [&](std::int64_t) {
        found = true;
        return false;
    });
    return found;
}

}  // namespace isohex::imaging::detail

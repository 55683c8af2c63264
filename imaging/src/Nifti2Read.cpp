// A NIfTI-2 file read with Debian's libnifti2 (nifti2_io) into a RawVolume.
// ITK 5.2's NIfTI reader knows NIfTI-1 only. libnifti2 exports the same
// function names as ITK's NIfTI-1 library (nifti_image_read, ...) with other
// structs, so it is not linked: it is opened with dlopen, local and
// deep-bound, so that neither library's calls reach the other's functions.
#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

#include <nifti2_io.h>

#include "FormatChecks.hpp"
#include "RawChecks.hpp"
#include "RawVolume.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {
namespace {

// libnifti2's two functions isohex calls, or null ones if it is missing.
struct Nifti2Library {
    decltype(&nifti_image_read) read = nullptr;
    decltype(&nifti_image_free) free = nullptr;
};

const Nifti2Library& nifti2Library() {
    static const Nifti2Library lib = [] {
        Nifti2Library l;
        if (void* h = dlopen("libnifti2.so.2", RTLD_NOW | RTLD_LOCAL | RTLD_DEEPBIND)) {
            l.read = reinterpret_cast<decltype(l.read)>(dlsym(h, "nifti_image_read"));
            l.free = reinterpret_cast<decltype(l.free)>(dlsym(h, "nifti_image_free"));
        }
        return l;
    }();
    return lib;
}

// The voxel at `i` of nifti2's buffer as float, for the real-valued types.
template <class T>
void copyAs(const void* data, std::int64_t first, std::vector<float>& out) {
    const T* v = static_cast<const T*>(data) + first;
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = static_cast<float>(v[i]);
}

bool copyVoxels(const nifti_image& nim, std::int64_t first, std::vector<float>& out) {
    switch (nim.datatype) {
        case DT_UINT8: copyAs<std::uint8_t>(nim.data, first, out); return true;
        case DT_INT8: copyAs<std::int8_t>(nim.data, first, out); return true;
        case DT_INT16: copyAs<std::int16_t>(nim.data, first, out); return true;
        case DT_UINT16: copyAs<std::uint16_t>(nim.data, first, out); return true;
        case DT_INT32: copyAs<std::int32_t>(nim.data, first, out); return true;
        case DT_UINT32: copyAs<std::uint32_t>(nim.data, first, out); return true;
        case DT_INT64: copyAs<std::int64_t>(nim.data, first, out); return true;
        case DT_UINT64: copyAs<std::uint64_t>(nim.data, first, out); return true;
        case DT_FLOAT32: copyAs<float>(nim.data, first, out); return true;
        case DT_FLOAT64: copyAs<double>(nim.data, first, out); return true;
        default: return false;
    }
}

const char* typeName(int datatype) {
    switch (datatype) {
        case DT_UINT8: return "uint8";
        case DT_INT8: return "int8";
        case DT_INT16: return "int16";
        case DT_UINT16: return "uint16";
        case DT_INT32: return "int32";
        case DT_UINT32: return "uint32";
        case DT_INT64: return "int64";
        case DT_UINT64: return "uint64";
        case DT_FLOAT32: return "float32";
        case DT_FLOAT64: return "float64";
        default: return "unknown";
    }
}

// The header's sizes, checked as for NIfTI-1: 3-D, or 4-D with a volume
// chosen by the volume index option. Returns the chosen frame.
std::int64_t chooseFrame(const std::string& file, const nifti_image& nim, const LoadOptions& options) {
    if (nim.ndim < 3 || nim.nu > 1 || nim.nv > 1 || nim.nw > 1)
        throw Error(file + ": a " + std::to_string(nim.ndim) + "-D NIfTI-2 image" +
                    (nim.ndim > 4 ? " (vectors or more dimensions)" : "") +
                    "; isohex needs a 3-D volume (or a 4-D image with the volume index option).");
    const std::int64_t frames = std::max<std::int64_t>(nim.nt, 1);
    const std::int64_t index = options.volumeIndex;
    if (frames > 1 && index < 0)
        throw Error(file + ": holds a 4-D image of " + std::to_string(frames) +
                    " volumes; isohex meshes one scalar volume. Choose one with the volume index option (0.." +
                    std::to_string(frames - 1) + ").");
    if (index >= frames || (frames == 1 && index > 0))
        throw Error(file + ": volume index " + std::to_string(index) + " is out of range; the file holds " +
                    std::to_string(frames) + " volume(s), so use 0.." + std::to_string(frames - 1) + ".");
    return std::max<std::int64_t>(index, 0);
}

// The geometry as ITK reads NIfTI: the sform if it has a code, else the qform
// (nifti2 makes it from pixdim when its code is 0), RAS turned into LPS.
void copyGeometry(const nifti_image& nim, RawVolume& raw) {
    const nifti_dmat44& m = nim.sform_code > 0 ? nim.sto_xyz : nim.qto_xyz;
    const double flip[3] = {-1, -1, 1};
    for (int a = 0; a < 3; ++a) {
        double norm = 0;
        for (int w = 0; w < 3; ++w) norm += m.m[w][a] * m.m[w][a];
        norm = std::sqrt(norm);
        raw.spacing[a] = norm;
        for (int w = 0; w < 3; ++w) raw.direction[3 * w + a] = norm > 0 ? flip[w] * m.m[w][a] / norm : 0;
        raw.origin[a] = flip[a] * m.m[a][3];
    }
}

}  // namespace

bool isNifti2(const std::filesystem::path& path) {
    std::string name = path.filename().string();
    for (auto& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    auto endsWith = [&](const char* e) {
        const std::size_t n = std::strlen(e);
        return name.size() >= n && name.compare(name.size() - n, n, e) == 0;
    };
    if (!endsWith(".nii") && !endsWith(".nii.gz")) return false;
    return niftiVersion(path.string()) == 2;
}

RawVolume readNifti2(const std::filesystem::path& path, const LoadOptions& options) {
    const std::string file = path.string();
    checkNiftiHeaderFields(file, file);
    checkNiftiOrientation(file);
    const Nifti2Library& lib = nifti2Library();
    if (!lib.read || !lib.free)
        throw Error(file + ": a NIfTI-2 file, which isohex reads with libnifti2 (Debian package libnifti2-2), and "
                    "that library is not installed. Install it, or save the image as NIfTI-1 and retry.");
    using Image = std::unique_ptr<nifti_image, decltype(lib.free)>;
    const Image header(lib.read(file.c_str(), 0), lib.free);
    if (!header) throw Error(file + ": the NIfTI-2 header cannot be read; the file is damaged, export it again.");
    const std::int64_t frame = chooseFrame(file, *header, options);
    RawHeader facts;
    facts.size = {header->nx, header->ny, header->nz, std::max<std::int64_t>(header->nt, 1)};
    checkMemoryBudget(file, facts, options.maxMemoryMB);
    const bool gz = file.size() > 3 && file.compare(file.size() - 3, 3, ".gz") == 0;
    checkNiftiDataSize(file, file, std::uint64_t(header->nvox) * std::uint64_t(header->nbyper), gz);
    if (std::string(typeName(header->datatype)) == "unknown")
        throw Error(file + ": the NIfTI-2 datatype " + std::to_string(header->datatype) +
                    " is not a real scalar type; isohex reads integer and float images. Convert it first.");
    const Image nim(lib.read(file.c_str(), 1), lib.free);
    if (!nim || !nim->data)
        throw Error(file + ": the NIfTI-2 voxel data cannot be read; the file is damaged, export it again.");
    RawVolume raw;
    raw.format = "NIfTI";
    raw.pixelType = typeName(nim->datatype);
    raw.dims = {nim->nx, nim->ny, nim->nz};
    raw.values.resize(static_cast<std::size_t>(raw.count()));
    copyVoxels(*nim, frame * raw.count(), raw.values);
    if (nim->scl_slope != 0 && std::isfinite(nim->scl_slope) && (nim->scl_slope != 1 || nim->scl_inter != 0))
        for (float& v : raw.values) v = static_cast<float>(v * nim->scl_slope + nim->scl_inter);
    copyGeometry(*nim, raw);
    if (!options.labels) restoreNiftiNonFinite(file, raw.values, frame, std::max<std::int64_t>(nim->nt, 1), 0);
    checkGeometry(raw, file);
    const bool integer = nim->datatype != DT_FLOAT32 && nim->datatype != DT_FLOAT64;
    if (options.labels) convertToLabels(raw, file, integer);
    return raw;
}

}  // namespace isohex::imaging::detail

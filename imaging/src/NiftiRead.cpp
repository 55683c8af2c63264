// .nii and .nii.gz files read with Debian's libnifti2 (nifti2_io) into a
// RawVolume, without ITK: NIfTI-2 files, which ITK 5.2's reader does not know,
// and NIfTI-1 files, which ITK's reader (ItkImageFile.cpp) read before. Its
// plugin (ITK with GDCM's dictionaries) took about 60 ms to load, most of the
// load stage of a small scan.
//
// A NIfTI-1 file gives the RawVolume ITK 5.2's NiftiImageIO and ImageFileReader
// give (and ItkImageFile.cpp makes of it): the same float values (scl_slope and
// scl_inter applied as ITK applies them), pixel type, spacing, origin and
// direction (ITK's choice between the sform and the qform, in its float
// arithmetic). Every case where that cannot be promised is left to ITK:
// readWithNiftiLib returns nothing and loadVolume reads the file with ITK. So
// are files ITK or isohex's checks refuse, so that the error is ITK's path's
// word for word (see nifti1Volume).
//
// libnifti2 exports the same function names as ITK's NIfTI-1 library
// (nifti_image_read, ...) with other structs, so it is not linked: it is
// opened with dlopen, local and deep-bound, so that neither library's calls
// reach the other's functions.
#include <dlfcn.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include <nifti2_io.h>

#include "FormatChecks.hpp"
#include "HeldStderr.hpp"
#include "RawChecks.hpp"
#include "RawVolume.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {
namespace {

// libnifti2's functions isohex calls, or null ones if it is missing.
struct NiftiLibrary {
    decltype(&nifti_image_read) read = nullptr;
    decltype(&nifti_image_free) free = nullptr;
};

const NiftiLibrary& niftiLibrary() {
    static const NiftiLibrary lib = [] {
        NiftiLibrary l;
        if (void* h = dlopen("libnifti2.so.2", RTLD_NOW | RTLD_LOCAL | RTLD_DEEPBIND)) {
            l.read = reinterpret_cast<decltype(l.read)>(dlsym(h, "nifti_image_read"));
            l.free = reinterpret_cast<decltype(l.free)>(dlsym(h, "nifti_image_free"));
            // Quiet (as ITK sets its own copy): isohex's own one-line error
            // names the file and the fault.
            if (auto debug = reinterpret_cast<decltype(&nifti_set_debug_level)>(dlsym(h, "nifti_set_debug_level")))
                debug(0);
        }
        return l;
    }();
    return lib;
}

using Image = std::unique_ptr<nifti_image, decltype(&nifti_image_free)>;

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

bool isFloatType(int datatype) { return datatype == DT_FLOAT32 || datatype == DT_FLOAT64; }

// Whether `name` ends in `suffix` (lower case), its letters in any case.
bool endsWithAnyCase(const std::string& name, const char* suffix) {
    const std::size_t n = std::strlen(suffix);
    if (name.size() < n) return false;
    for (std::size_t i = 0; i < n; ++i)
        if (std::tolower(static_cast<unsigned char>(name[name.size() - n + i])) != suffix[i]) return false;
    return true;
}

// A name ending in .gz, in any case (as ItkImageFile.cpp tells .nii.gz).
bool gzipName(const std::string& file) { return endsWithAnyCase(file, ".gz"); }

// ---------------------------------------------------------------------------
// NIfTI-2

// The header's sizes, checked: 3-D, or 4-D with a volume chosen by the volume
// index option. Returns the chosen frame.
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

// A NIfTI-2 file's geometry: the sform if it has a code, else the qform
// (nifti2 makes it from pixdim when its code is 0), RAS turned into LPS.
// ITK 5.2 reads no NIfTI-2 file, so there is no ITK result to match; its
// NIfTI-1 rule (itkNiftiGeometry below) depends on float round-off of its
// own and is not repeated here.
void copyNifti2Geometry(const nifti_image& nim, RawVolume& raw) {
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

RawVolume nifti2Volume(const std::string& file, const NiftiLibrary& lib, const LoadOptions& options) {
    checkNiftiHeaderFields(file, file);
    checkNiftiOrientation(file);
    if (!lib.read || !lib.free)
        throw Error(file + ": a NIfTI-2 file, which isohex reads with libnifti2 (Debian package libnifti2-2), and "
                    "that library is not installed. Install it, or save the image as NIfTI-1 and retry.");
    const Image header(lib.read(file.c_str(), 0), lib.free);
    if (!header) throw Error(file + ": the NIfTI-2 header cannot be read; the file is damaged, export it again.");
    const std::int64_t frame = chooseFrame(file, *header, options);
    RawHeader facts;
    facts.size = {header->nx, header->ny, header->nz, std::max<std::int64_t>(header->nt, 1)};
    checkMemoryBudget(file, facts, options.maxMemoryMB);
    checkNiftiDataSize(file, file, std::uint64_t(header->nvox) * std::uint64_t(header->nbyper), gzipName(file));
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
    copyNifti2Geometry(*nim, raw);
    if (!options.labels) restoreNiftiNonFinite(file, raw.values, frame, std::max<std::int64_t>(nim->nt, 1), 0);
    checkGeometry(raw, file);
    if (options.labels) convertToLabels(raw, file, !isFloatType(nim->datatype));
    return raw;
}

// ---------------------------------------------------------------------------
// NIfTI-1, as ITK 5.2 reads it
//
// ITK's NIfTI-1 library (nifti1_io, bundled with ITK) keeps the header's
// transforms as float matrices (mat44); libnifti2 keeps them in double. The
// functions below rebuild ITK's float matrices from libnifti2's fields (which
// hold the header's float values exactly) and repeat, in the same float
// operations, NiftiImageIO::SetImageIOOrientationFromNIfTI's choice between
// them (ITK 5.2.1, Modules/IO/NIFTI/src/itkNiftiImageIO.cxx), with vnl's
// float arithmetic spelled out (vnl_matrix_fixed, vnl_c_vector).

using Mat44f = std::array<std::array<float, 4>, 4>;

// ITK's qto_xyz: nifti1_io's nifti_quatern_to_mat44, whose long double terms
// are rounded to float once (libnifti2 rounds the same terms to double, and
// rounding that to float again could differ in the last bit). Without a
// qform code, the grid spacings on the diagonal.
Mat44f itkQform(const nifti_image& nim) {
    Mat44f r{};
    r[3][3] = 1.0f;
    const auto dx = static_cast<float>(nim.dx), dy = static_cast<float>(nim.dy), dz = static_cast<float>(nim.dz);
    if (nim.qform_code <= 0) {
        r[0][0] = dx;
        r[1][1] = dy;
        r[2][2] = dz;
        return r;
    }
    // nifti1_io: float arguments, double variables, long double literals.
    const auto qb = static_cast<float>(nim.quatern_b), qc = static_cast<float>(nim.quatern_c),
               qd = static_cast<float>(nim.quatern_d);
    double a = 0, b = qb, c = qc, d = qd;
    a = static_cast<double>(1.0L - (b * b + c * c + d * d));
    if (a < 1.e-7L) {
        a = static_cast<double>(1.0L / std::sqrt(b * b + c * c + d * d));
        b *= a;
        c *= a;
        d *= a;
        a = 0.0;
    } else {
        a = std::sqrt(a);
    }
    const double xd = dx > 0.0 ? dx : 1.0, yd = dy > 0.0 ? dy : 1.0;
    double zd = dz > 0.0 ? dz : 1.0;
    if (static_cast<float>(nim.qfac) < 0.0) zd = -zd;
    r[0][0] = static_cast<float>((a * a + b * b - c * c - d * d) * xd);
    r[0][1] = static_cast<float>(2.0L * (b * c - a * d) * yd);
    r[0][2] = static_cast<float>(2.0L * (b * d + a * c) * zd);
    r[1][0] = static_cast<float>(2.0L * (b * c + a * d) * xd);
    r[1][1] = static_cast<float>((a * a + c * c - b * b - d * d) * yd);
    r[1][2] = static_cast<float>(2.0L * (c * d - a * b) * zd);
    r[2][0] = static_cast<float>(2.0L * (b * d - a * c) * xd);
    r[2][1] = static_cast<float>(2.0L * (c * d + a * b) * yd);
    r[2][2] = static_cast<float>((a * a + d * d - c * c - b * b) * zd);
    r[0][3] = static_cast<float>(nim.qoffset_x);
    r[1][3] = static_cast<float>(nim.qoffset_y);
    r[2][3] = static_cast<float>(nim.qoffset_z);
    return r;
}

// ITK's sto_xyz: the srow rows, or all zeros without an sform code.
Mat44f itkSform(const nifti_image& nim) {
    Mat44f s{};
    if (nim.sform_code <= 0) return s;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) s[i][j] = static_cast<float>(nim.sto_xyz.m[i][j]);
    return s;
}

// One of ITK's yes-or-no answers, and whether it is sure: a comparison whose
// value lies within a thousandth of its tolerance (where a slip in repeating
// ITK's float arithmetic could turn it) is not, nor is IsAffine's (see
// itkIsAffine).
struct Verdict {
    bool value = false;
    bool sure = true;
};

// `value > tol`, as ITK compares.
Verdict above(double value, double tol) { return {value > tol, std::fabs(value - tol) > 1e-3 * tol}; }
Verdict negate(Verdict v) { return {!v.value, v.sure}; }
// `a && b`: sure when either is surely false.
Verdict both(Verdict a, Verdict b) {
    if ((a.sure && !a.value) || (b.sure && !b.value)) return {false, true};
    return {a.value && b.value, a.sure && b.sure};
}

// vnl_matrix_fixed::is_equal on the 3x3 rotation-and-scale parts.
Verdict rotationsEqual(const Mat44f& s, const Mat44f& q, double tol) {
    Verdict equal{true, true};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            const float diff = s[i][j] - q[i][j];
            equal = both(equal, negate(above(std::fabs(diff), tol)));
        }
    return equal;
}

// vnl's one_norm of the difference of two float 4-vectors (summed in float).
float oneNormOfDifference(const std::array<float, 4>& x, const std::array<float, 4>& y) {
    float sum = 0;
    for (std::size_t i = 0; i < 4; ++i) {
        const float diff = x[i] - y[i];
        sum += std::fabs(diff);
    }
    return sum;
}

std::array<float, 4> column(const Mat44f& m, int j) { return {m[0][j], m[1][j], m[2][j], m[3][j]}; }

// vnl_matrix_fixed's product a * b^T (float, summed in order).
template <std::size_t N>
std::array<std::array<float, N>, N> timesTransposed(const std::array<std::array<float, N>, N>& a,
                                                    const std::array<std::array<float, N>, N>& b) {
    std::array<std::array<float, N>, N> out{};
    for (std::size_t i = 0; i < N; ++i)
        for (std::size_t j = 0; j < N; ++j) {
            float accum = a[i][0] * b[j][0];
            for (std::size_t k = 1; k < N; ++k) accum += a[i][k] * b[j][k];
            out[i][j] = accum;
        }
    return out;
}

// vnl_matrix_fixed::is_identity(tol).
template <std::size_t N>
Verdict isIdentity(const std::array<std::array<float, N>, N>& m, double tol) {
    Verdict identity{true, true};
    for (std::size_t i = 0; i < N; ++i)
        for (std::size_t j = 0; j < N; ++j) {
            const float dev = i == j ? std::fabs(m[i][j] - 1.0f) : std::fabs(m[i][j]);
            identity = both(identity, negate(above(dev, tol)));
        }
    return identity;
}

// IsAffine (itkNiftiImageIO.cxx) on the sform, as far as it can be known
// without ITK: false when its last row is not (0 0 0 1) or its determinant is
// clearly at most 1e-5; otherwise unsure. Beyond that IsAffine compares,
// within 1e-2, the inverse of the 4x4 matrix with that of its 3x3 part, both
// through vnl's single-precision SVD, whose round-off alone reaches 1e-2 for
// ordinary headers (0.5 mm voxels 300 mm from the origin gave up to 0.17),
// so that only ITK knows its answer.
Verdict itkIsAffine(const Mat44f& s) {
    float bottom = std::fabs(s[3][3] - 1.0f);
    for (int i = 0; i < 3; ++i) bottom += std::fabs(s[3][i]);
    if (bottom > std::numeric_limits<float>::epsilon()) return {false, true};
    const double det = double(s[0][0]) * (double(s[1][1]) * s[2][2] - double(s[1][2]) * s[2][1]) -
                       double(s[0][1]) * (double(s[1][0]) * s[2][2] - double(s[1][2]) * s[2][0]) +
                       double(s[0][2]) * (double(s[1][0]) * s[2][1] - double(s[1][1]) * s[2][0]);
    if (std::fabs(det) < 0.5e-5) return {false, true};
    return {true, false};
}

// The rest of ITK's sform_decomposable_without_skew: each column's length
// within 1e-3 of the grid spacing, and the columns, normalised as vnl does,
// orthonormal within 1e-4.
Verdict itkSformScaledOrthonormal(const nifti_image& nim, const Mat44f& s) {
    const float spacing[3] = {static_cast<float>(nim.dx), static_cast<float>(nim.dy), static_cast<float>(nim.dz)};
    std::array<std::array<float, 3>, 3> rows{};  // the rotation, its columns normalised
    Verdict scaled{true, true};
    for (int j = 0; j < 3; ++j) {
        float squares = 0;  // vnl's two_norm: float squares summed in float, sqrt in double
        for (int i = 0; i < 3; ++i) squares += s[i][j] * s[i][j];
        const auto length = static_cast<float>(std::sqrt(static_cast<double>(squares)));
        const float diff = spacing[j] - length;
        scaled = both(scaled, negate(above(std::fabs(diff), 1e-3f)));
        // vnl_c_vector::normalize: times float(1 / sqrt(the float sum of squares))
        const float inverse = squares != 0 ? static_cast<float>(1.0 / std::sqrt(static_cast<double>(squares))) : 1.0f;
        for (int i = 0; i < 3; ++i) rows[i][j] = squares != 0 ? inverse * s[i][j] : s[i][j];
    }
    return both(scaled, isIdentity(timesTransposed(rows, rows), 1.0e-4));
}

enum class Form { Sform, Qform, None };

// ITK's orientation matrix for a header with a qform or sform code (ITK
// 5.2.1's SetImageIOOrientationFromNIfTI): the sform or the qform. Empty when
// ITK refuses the header ("No orthonormal definition found") or when its
// choice hangs on an answer that is not sure here and the choices differ.
std::optional<Mat44f> itkNiftiMatrix(const nifti_image& nim) {
    const Mat44f s = itkSform(nim), q = itkQform(nim);
    const int qcode = nim.qform_code > 0 ? nim.qform_code : 0, scode = nim.sform_code > 0 ? nim.sform_code : 0;
    // qform_sform_are_similar: rotations within 1e-5, translations and last
    // rows within 1e-7 (one-norm).
    const std::array<float, 4> sRow{s[3][0], s[3][1], s[3][2], s[3][3]}, qRow{q[3][0], q[3][1], q[3][2], q[3][3]};
    const Verdict similar =
        both(rotationsEqual(s, q, 1e-5), both(negate(above(oneNormOfDifference(column(s, 3), column(q, 3)), 1e-7)),
                                              negate(above(oneNormOfDifference(sRow, qRow), 1e-7))));
    const Verdict decomposable = both(itkIsAffine(s), itkSformScaledOrthonormal(nim, s));
    // sform_and_qform_are_very_similar: sform * qform^T the identity within 1e-4.
    const Verdict verySimilar = isIdentity(timesTransposed(s, q), 1.0e-4);

    // The choice for given answers; every combination of the unsure ones is
    // tried, and must come to the same matrix.
    auto choose = [&](bool isSimilar, bool isDecomposable, bool isVerySimilar) {
        bool preferS = isSimilar;
        if ((!isSimilar || scode != 0) && isDecomposable) {
            if (qcode == 0 && scode != 0)
                preferS = true;
            else if (scode == NIFTI_XFORM_SCANNER_ANAT)
                preferS = true;
            else if (qcode != 0 && scode != 0)
                preferS = isVerySimilar;
        }
        return preferS ? Form::Sform : qcode != 0 ? Form::Qform : Form::None;
    };
    auto options = [](Verdict v) { return v.sure ? std::vector<bool>{v.value} : std::vector<bool>{false, true}; };
    std::optional<Form> form;
    for (bool a : options(similar))
        for (bool b : options(decomposable))
            for (bool c : options(verySimilar)) {
                const Form f = choose(a, b, c);
                if (f == Form::None) return std::nullopt;
                if (form && *form != f) {
                    for (int i = 0; i < 3; ++i)  // the sform and qform are then one matrix, or ITK's choice is unknown
                        for (int j = 0; j < 4; ++j)
                            if (!(s[i][j] == q[i][j])) return std::nullopt;
                }
                form = f;
            }
    return *form == Form::Sform ? s : q;
}

// NiftiImageIO's Normalize: divides by the length, left as it is when zero.
void normalize(std::array<double, 3>& x) {
    double sum = 0.0;
    for (double v : x) sum += v * v;
    if (sum == 0.0) return;
    sum = std::sqrt(sum);
    for (double& v : x) v = v / sum;
}

// The origin, spacing and direction ITK's ImageFileReader gives the image,
// or false where ITK's choice of matrix cannot be repeated (itkNiftiMatrix).
// The spacing is pixdim (times the unit: meter 1000, micron 0.001), not the
// matrix's column lengths; a negative spacing turns its axis around.
bool itkNiftiGeometry(const nifti_image& nim, RawVolume& raw) {
    raw.origin = {0, 0, 0};
    raw.direction = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    if (nim.qform_code > 0 || nim.sform_code > 0) {
        const std::optional<Mat44f> m = itkNiftiMatrix(nim);
        if (!m) return false;
        raw.origin = {-double((*m)[0][3]), -double((*m)[1][3]), double((*m)[2][3])};
        for (int a = 0; a < 3; ++a) {
            std::array<double, 3> axis{-double((*m)[0][a]), -double((*m)[1][a]), double((*m)[2][a])};
            normalize(axis);
            for (int w = 0; w < 3; ++w) raw.direction[static_cast<std::size_t>(3 * w + a)] = axis[static_cast<std::size_t>(w)];
        }
    }
    double unit = 1.0;
    switch (XYZT_TO_SPACE(nim.xyz_units)) {
        case NIFTI_UNITS_METER: unit = 1e3; break;
        case NIFTI_UNITS_MICRON: unit = 1e-3; break;
        default: break;
    }
    const double spacing[3] = {double(static_cast<float>(nim.dx)) * unit, double(static_cast<float>(nim.dy)) * unit,
                               double(static_cast<float>(nim.dz)) * unit};
    for (int a = 0; a < 3; ++a) {
        raw.spacing[a] = spacing[a];
        if (spacing[a] < 0) {
            raw.spacing[a] = -spacing[a];
            for (int w = 0; w < 3; ++w) raw.direction[static_cast<std::size_t>(3 * w + a)] *= -1.0;
        }
    }
    return true;
}

// The number of dimensions ITK gives a scalar image: dim[0] less trailing
// sizes of 1 beyond the third.
int itkDimensions(const nifti_image& nim) {
    auto realdim = static_cast<int>(nim.dim[0]);
    while (realdim > 3 && nim.dim[realdim] == 1) --realdim;
    return realdim;
}

// The scale ITK applies to the voxels: slope 0 means 1, and nothing is done
// unless the slope differs from 1 or the intercept from 0 by more than the
// double epsilon.
struct ItkRescale {
    double slope = 1, inter = 0;
    bool apply = false;
    explicit ItkRescale(const nifti_image& nim) : slope(nim.scl_slope), inter(nim.scl_inter) {
        const double eps = std::numeric_limits<double>::epsilon();
        if (std::abs(slope) < eps) slope = 1;
        apply = std::abs(slope) > eps && (std::abs(slope - 1.0) > eps || std::abs(inter) > eps);
    }
    // RescaleFunction: the value times the slope, plus the intercept, in double.
    double operator()(double v) const {
        double tmp = v * slope;
        tmp += inter;
        return tmp;
    }
};

// A NIfTI-1 file's RawVolume as readImageFileItk makes it, or nothing where
// that is not sure (the reasons are listed inside). Throws what isohex's
// checks throw; the caller leaves such files to ITK too.
std::optional<RawVolume> nifti1Volume(const std::string& file, const NiftiLibrary& lib, const LoadOptions& options) {
    // ITK reads a region alone (streamed, and without putting the
    // non-finite voxels back) and lets GDCM try every file marked DICM.
    if (!options.region.empty() || !lib.read || !lib.free) return std::nullopt;
    if (std::FILE* f = std::fopen(file.c_str(), "rb")) {
        char mark[4] = {};
        const bool marked = std::fseek(f, 128, SEEK_SET) == 0 && std::fread(mark, 1, 4, f) == 4 &&
                            std::memcmp(mark, "DICM", 4) == 0;
        std::fclose(f);
        if (marked) return std::nullopt;
    }
    // An Analyze 7.5 header in a .nii file, or another magic: ITK reads
    // those (with a warning) or refuses them.
    if (!niftiOneFileMagic(file)) return std::nullopt;
    // ItkImageFile.cpp's checks before ITK reads the header.
    checkNiftiHeaderFields(file, file);
    checkNiftiOrientation(file);
    const Image header(lib.read(file.c_str(), 0), lib.free);
    if (!header) return std::nullopt;  // ITK's message for an unreadable header
    const nifti_image& h = *header;
    // Only one real scalar per voxel, 3-D or 4-D as ITK counts dimensions,
    // is read here: ITK's intents for vectors and matrices, other types and
    // dimensions (ITK refuses them or reads them otherwise) are left to it.
    const int dims = itkDimensions(h);
    if (h.nifti_type != NIFTI_FTYPE_NIFTI1_1 || (dims != 3 && dims != 4) ||
        std::string(typeName(h.datatype)) == "unknown" || h.intent_code == NIFTI_INTENT_VECTOR ||
        h.intent_code == NIFTI_INTENT_SYMMATRIX || h.intent_code == NIFTI_INTENT_GENMATRIX)
        return std::nullopt;
    // ItkImageFile.cpp's checkVolumeChoice; ITK words its refusals.
    const std::int64_t frames = dims == 4 ? h.nt : 1, index = options.volumeIndex;
    if (frames > 1 ? index < 0 || index >= frames : index > 0) return std::nullopt;
    const std::int64_t frame = frames > 1 ? index : 0;
    RawVolume raw;
    if (!itkNiftiGeometry(h, raw)) return std::nullopt;
    // ITK reports integers it rescales as float (the file holds the integers).
    const ItkRescale rescale(h);
    const bool promoted = rescale.apply && !isFloatType(h.datatype);
    RawHeader facts;
    facts.size = {h.nx, h.ny, h.nz, frames};
    checkMemoryBudget(file, facts, options.maxMemoryMB);
    const std::uint64_t voxels = std::uint64_t(h.nx) * std::uint64_t(h.ny) * std::uint64_t(h.nz) * std::uint64_t(frames);
    checkNiftiDataSize(file, file, voxels * std::uint64_t(h.nbyper), gzipName(file));

    if (options.progress) options.progress("read", 0.0);
    const Image nim(lib.read(file.c_str(), 1), lib.free);
    if (!nim || !nim->data) return std::nullopt;
    if (options.progress) options.progress("read", 1.0);
    raw.format = "NIfTI";
    raw.pixelType = promoted ? "float32" : typeName(nim->datatype);
    raw.dims = {nim->nx, nim->ny, nim->nz};
    raw.fileDims = raw.dims;
    const std::int64_t n = raw.count();
    raw.values.resize(static_cast<std::size_t>(n));
    if (nim->datatype == DT_FLOAT64 && rescale.apply) {
        // rescaled in double, then converted to float
        const double* v = static_cast<const double*>(nim->data) + frame * n;
        for (std::int64_t i = 0; i < n; ++i) raw.values[static_cast<std::size_t>(i)] = static_cast<float>(rescale(v[i]));
    } else {
        copyVoxels(*nim, frame * n, raw.values);  // integers promoted to float first
        if (rescale.apply)
            for (float& v : raw.values) v = static_cast<float>(rescale(v));
    }
    // ItkImageFile.cpp: restoreNonFinite, then finish.
    if (!options.labels) restoreNiftiNonFinite(file, raw.values, frame, frames, 0);
    checkGeometry(raw, file);
    if (options.labels) convertToLabels(raw, file, !promoted && !isFloatType(nim->datatype));
    return raw;
}

}  // namespace

int niftiFileVersion(const std::filesystem::path& path) {
    const std::string name = path.filename().string();
    if (!endsWithAnyCase(name, ".nii") && !endsWithAnyCase(name, ".nii.gz")) return 0;
    return niftiVersion(path.string());
}

bool readsWithNiftiLib(const std::filesystem::path& path) { return niftiFileVersion(path) != 0; }

std::optional<RawVolume> readWithNiftiLib(const std::filesystem::path& path, const LoadOptions& options) {
    const std::string file = path.string();
    const NiftiLibrary& lib = niftiLibrary();
    HeldStderr held;  // libnifti2 prints "** ERROR: ..." whatever its debug level
    if (niftiFileVersion(path) == 2) {
        RawVolume raw = nifti2Volume(file, lib, options);
        held.replay();
        return raw;
    }
    // NIfTI-1: whatever isohex's checks or the libraries refuse is refused
    // by ITK's path, in its words.
    std::optional<RawVolume> raw;
    try {
        raw = nifti1Volume(file, lib, options);
    } catch (const Error&) {
        return std::nullopt;
    } catch (const std::bad_alloc&) {
        return std::nullopt;
    }
    if (raw) held.replay();
    return raw;
}

bool loadNiftiLib() {
    const NiftiLibrary& lib = niftiLibrary();
    return lib.read && lib.free;
}

}  // namespace isohex::imaging::detail

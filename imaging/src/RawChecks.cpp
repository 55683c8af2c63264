// The checks every reader runs on the RawVolume it made (see RawChecks.hpp).
#include "RawChecks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>

#include "isohex/core/Error.hpp"
#include "isohex/core/SettingError.hpp"

namespace isohex::imaging::detail {

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

void throwSheared(const std::string& file, const std::string& detail) {
    throw Error(file + ": the image's axes are not perpendicular (" + detail +
                "): its voxels are sheared, and isohex meshes grids whose axes are perpendicular (ITK refuses "
                "sheared NIfTI files alike). Resample the image onto a grid with perpendicular axes (e.g. with "
                "ITK's ResampleImageFilter or 3D Slicer) and retry.");
}

// ITK reads NRRD space directions and a MetaImage TransformMatrix that are
// not perpendicular as they are (the NIfTI reader refuses them): the mesh,
// built on the voxel grid, then did not follow the isosurface. Within 1e-4
// of perpendicular (directions written to six decimals pass).
void checkAxesPerpendicular(const std::array<double, 9>& D, const std::string& file) {
    for (int a = 0; a < 3; ++a)
        for (int b = a + 1; b < 3; ++b) {
            double dot = 0, na = 0, nb = 0;
            for (int w = 0; w < 3; ++w) {
                dot += D[3 * w + a] * D[3 * w + b];
                na += D[3 * w + a] * D[3 * w + a];
                nb += D[3 * w + b] * D[3 * w + b];
            }
            const double cosine = dot / std::sqrt(na * nb);
            if (std::fabs(cosine) > 1e-4) {
                std::ostringstream m;
                m.precision(4);
                m << "axes " << a << " and " << b << " meet at " << std::acos(std::clamp(cosine, -1.0, 1.0)) * 180.0 / M_PI
                  << " degrees";
                throwSheared(file, m.str());
            }
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
    checkAxesPerpendicular(D, file);
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

}  // namespace isohex::imaging::detail

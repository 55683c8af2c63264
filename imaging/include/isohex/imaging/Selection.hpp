#pragma once
// Selection: which part of a loaded volume is the solid to mesh, as one
// ImplicitField per material.
//
// Intensity volumes give one material (id 1) bounded by an iso-surface; the
// iso value is given or chosen by Otsu's method. Label volumes give one
// material per selected label, each bounded by the 0.5 level of its
// (optionally smoothed) indicator function: trilinear interpolation of the
// 0/1 indicator puts the surface half-way between a voxel of the label and
// its neighbour, the same place a marching-cubes segmentation surface has.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "isohex/imaging/ImplicitField.hpp"
#include "isohex/imaging/Volume.hpp"

namespace isohex::imaging {

struct SelectOptions {
    // Intensity: the surface level. Empty = Otsu's threshold (a level-set VDB
    // grid defaults to 0 with inside below instead).
    std::optional<double> iso;
    // `iso` is Otsu's threshold of the whole scan (a part's window is
    // selected with it): the window is then checked for a label map as a
    // scan whose threshold select() chooses is.
    bool isoFromOtsu = false;
    // Inside is where intensity < iso (e.g. pores, dark objects). Default:
    // inside is where intensity > iso.
    bool insideBelow = false;
    // Labels: which labels to mesh; empty = every non-zero label present.
    // Label 0 is background and cannot be selected.
    std::vector<std::int32_t> labels;
    // Labels with fewer voxels than this are dropped (and reported).
    std::int64_t minLabelVoxels = 8;
    // Gaussian pre-smoothing, standard deviation in world units (mm); 0 = none.
    double smoothSigma = 0.0;
    Interpolation interpolation = Interpolation::Trilinear;
    Progress progress;
};

struct Material {
    std::int32_t id = 1;          // label value, or 1 for an intensity solid
    std::int64_t voxels = 0;      // voxels inside (before smoothing)
    ImplicitField field;          // < 0 inside
};

struct DroppedLabel {
    std::int32_t label = 0;
    std::int64_t voxels = 0;
};

struct Selection {
    std::vector<Material> materials;
    // Intensity only: the level used and whether Otsu chose it.
    std::optional<double> iso;
    bool isoFromOtsu = false;
    bool insideBelow = false;
    std::vector<DroppedLabel> dropped;  // below minLabelVoxels
};

// Throws isohex::Error when the selection is empty (iso outside the data
// range, no requested label present, every label too small, ...).
Selection select(const Volume& volume, const SelectOptions& options = {});

// Separable Gaussian blur of a dense x-fastest volume; sigma in world units,
// converted per axis with the spacing; edges replicate the border voxels.
void gaussianSmooth(std::vector<float>& values, const openvdb::Coord& dims, const Vec3& spacing,
                    double sigma);

}  // namespace isohex::imaging

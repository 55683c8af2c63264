#pragma once
// A scan loaded into an OpenVDB grid together with its physical transform.
//
// World space is ITK's physical space (LPS millimetres for medical images):
// the centre of voxel (i,j,k) sits at origin + D * diag(spacing) * (i,j,k),
// with D the image's direction cosines. The grid's transform is exactly that
// affine map, so `grid->transform().indexToWorld(ijk)` gives ITK's
// TransformIndexToPhysicalPoint.
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>

#include <openvdb/openvdb.h>

#include "isohex/core/HexMesh.hpp"  // Vec3
#include "isohex/core/Progress.hpp"

namespace isohex::imaging {

enum class VolumeKind { Intensity, Labels };

struct LoadOptions {
    // Read integer images as label maps (Int32Grid). Without it every image is
    // an intensity image (FloatGrid). A float image is accepted as labels only
    // when all of its values are integers.
    bool labels = false;
    // For a 4-D image (several volumes) or a multi-component image (vectors,
    // RGB, ...): which volume / component to take. -1 = refuse such images.
    int volumeIndex = -1;
    // DICOM folder: the SeriesInstanceUID to read. Empty = the series with the
    // most slices (an error lists the series when that choice is ambiguous).
    std::string seriesUid;
    // .vdb file: the grid to read. Empty = the first float grid (the first
    // integer grid when `labels` is set).
    std::string gridName;
    // Folder of 2-D slices without geometry (OpenEXR, TIFF): voxel spacing and
    // the position of voxel (0,0,0), in mm. Slices are stacked in file-name
    // order (numbers compared by value), rows along +y, slices along +z.
    Vec3 sliceSpacing{1.0, 1.0, 1.0};
    Vec3 sliceOrigin{0.0, 0.0, 0.0};
    // NaN / Inf voxels are an error unless this is set; then they are kept in
    // the grid and every selection treats them as outside.
    bool nanAsOutside = false;
    // A header (.nhdr, .mhd) may name data files only in its own folder or
    // below it unless this is set; devices, pipes, folders and the header
    // itself are refused either way.
    bool allowDataOutside = false;
    // Refuse volumes whose estimated peak memory while loading exceeds this
    // many MiB. 0 = 80 % of the machine's physical memory.
    double maxMemoryMB = 0.0;
    Progress progress;
    // Called with each file of a folder (a DICOM series' folder) just before
    // a library opens it, so that a crash inside the library can be put down
    // to that file; may be empty.
    std::function<void(const std::string& file)> reading;
    // Read only these voxels (index box of the file's voxels; empty = all).
    // The Volume's box is then this box (clipped to the file), in the file's
    // own voxel indices. ITK's readers read only the region from formats that
    // stream (NIfTI-1, also gzipped, decompressed from the file's start up to
    // the region; uncompressed MetaImage: Volume::regionStreamed);
    // every other input is read whole and cropped (a .vdb is read whole and
    // not cropped). A NIfTI file's non-finite
    // voxels read as 0 then (ITK zeroes them; the whole read restores them).
    openvdb::CoordBBox region;
};

struct Volume {
    VolumeKind kind = VolumeKind::Intensity;
    openvdb::FloatGrid::Ptr intensity;  // set when kind == Intensity
    openvdb::Int32Grid::Ptr labels;     // set when kind == Labels

    // Index box of the scanned region; every voxel in it is active, voxels
    // outside it read the grid background.
    openvdb::CoordBBox box;
    // Geometry as read (also encoded in the grids' transform).
    Vec3 origin{0, 0, 0};
    Vec3 spacing{1, 1, 1};
    std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};  // row-major, columns = axes

    // Range of the finite voxel values; the intensity background is `minValue`.
    double minValue = 0.0;
    double maxValue = 0.0;
    std::int64_t nonFiniteVoxels = 0;  // only non-zero with LoadOptions::nanAsOutside

    std::string source;      // the path given
    std::string format;      // "NIfTI", "NRRD", "MetaImage", "TIFF", "DICOM", "OpenVDB", "OpenEXR"
    std::string pixelType;   // the file's component type, e.g. "uint8", "float32"
    std::string seriesUid;   // DICOM only
    bool levelSet = false;   // an OpenVDB grid of class level set (inside < 0)
    // With LoadOptions::region: the file's own voxel dimensions, and whether
    // the reader read the region alone (false: the whole file, then cropped).
    openvdb::Coord fileDims{0, 0, 0};
    bool regionStreamed = false;

    const openvdb::math::Transform& transform() const {
        return kind == VolumeKind::Labels ? labels->transform() : intensity->transform();
    }
    openvdb::Coord dims() const { return box.dim(); }
    std::int64_t voxelCount() const { return static_cast<std::int64_t>(box.volume()); }
};

// Reads a scan. The format follows from the path: .nii/.nii.gz through
// libnifti2 (a NIfTI-1 file as ITK reads it; some, and regions, through ITK);
// .nrrd/.nhdr, .mha/.mhd, .tif/.tiff (multi-page) and DICOM through ITK; .vdb
// through OpenVDB; a folder of DICOM files, of .exr slices (single-channel
// float) or of .tif slices. Throws isohex::Error naming the file, the problem
// and the fix.
Volume loadVolume(const std::filesystem::path& path, const LoadOptions& options = {});

// The affine transform for origin + D * diag(spacing) * ijk.
openvdb::math::Transform::Ptr makeTransform(const Vec3& origin, const Vec3& spacing,
                                            const std::array<double, 9>& direction);

}  // namespace isohex::imaging

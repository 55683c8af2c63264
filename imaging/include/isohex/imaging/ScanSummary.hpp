#pragma once
// The whole-scan facts a part of a split scan needs (docs/SPLIT-SCANS.md),
// gathered by reading the scan a few slices at a time, so that a part can
// then read only its window: the value range, the iso value (given, or
// Otsu's from the whole scan's histogram), and which voxels are selected
// (their box and their count per voxel layer along each axis).
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <openvdb/openvdb.h>

#include "isohex/imaging/Selection.hpp"
#include "isohex/imaging/Volume.hpp"

namespace isohex::imaging {

struct ScanSummary {
    openvdb::Coord dims{0, 0, 0};  // the file's voxels
    std::string format, pixelType;
    Vec3 origin{0, 0, 0}, spacing{1, 1, 1};  // geometry as read (Volume's)
    std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};
    double minValue = 0, maxValue = 0;  // finite values
    double iso = 0;
    bool isoFromOtsu = false;
    bool insideBelow = false;
    // Selected voxels: those whose field sign * (value - iso), in float as
    // select() computes it, is below 0 (sign -1, or +1 with insideBelow).
    std::int64_t selectedVoxels = 0;
    openvdb::CoordBBox solid;                           // their index box
    std::array<std::vector<std::int64_t>, 3> perLayer;  // their count per voxel layer along x, y, z
    int passes = 0;                                     // times the file was read through
    std::int64_t slabReads = 0;                         // regions read
};

// Summarises an intensity scan slab by slab. Empty when the scan cannot be
// read that way without reading it whole each time: a folder, a .vdb, a
// NIfTI-2 file, a format whose reader does not stream (gzip-compressed
// NIfTI or MetaImage, NRRD, TIFF, DICOM; see LoadOptions::region), label maps,
// Gaussian smoothing, non-finite voxels kept (nanAsOutside). The selection
// scans select() would refuse (an iso value outside the value range, no voxel
// selected, no Otsu threshold, non-finite voxels) are empty too, so that the
// whole read gives select()'s error. Each read holds whole slices of about
// `voxelsPerRead` voxels (at least one slice).
std::optional<ScanSummary> summarizeScan(const std::filesystem::path& path, const LoadOptions& load,
                                         const SelectOptions& select, std::int64_t voxelsPerRead = 1 << 20);

}  // namespace isohex::imaging

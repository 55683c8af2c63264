#pragma once
// Internal: a dense 3-D array plus geometry, the hand-over format between the
// file readers (ITK, libnifti2, OpenEXR) and the grid builder. No ITK or
// OpenVDB here, so the ITK translation units and the OpenVDB ones compile
// independently.
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "isohex/imaging/Volume.hpp"

namespace isohex::imaging::detail {

struct RawVolume {
    std::array<std::int64_t, 3> dims{0, 0, 0};  // x fastest in the buffers
    std::array<std::int64_t, 3> start{0, 0, 0};  // the file's voxel index of the buffers' first voxel
    std::array<std::int64_t, 3> fileDims{0, 0, 0};  // the whole file's (dims, unless a region was read)
    bool streamed = false;                       // a region read without reading the rest of the file
    std::vector<float> values;                  // intensity, or
    std::vector<std::int32_t> labels;           // labels (exactly one is filled)
    Vec3 origin{0, 0, 0};
    Vec3 spacing{1, 1, 1};
    std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};
    std::string format;
    std::string pixelType;
    std::string seriesUid;
    std::int64_t count() const { return dims[0] * dims[1] * dims[2]; }
};

// Header facts used for the memory check before any bulk read.
struct RawHeader {
    std::array<std::int64_t, 4> size{1, 1, 1, 1};  // x, y, z, t
    int dimensions = 3;
    int components = 1;
    int bytesPerComponent = 4;
};

// Estimated peak bytes while loading a volume with this header: the reader's
// buffer of the whole file, the extracted dense copy and the grid.
double estimatePeakBytes(const RawHeader& header);
// Throws when the estimate exceeds the budget (0 = 80 % of physical memory).
void checkMemoryBudget(const std::string& file, const RawHeader& header, double maxMemoryMB);

// ITK: one image file (NIfTI, NRRD, MetaImage, TIFF, a single DICOM file).
RawVolume readImageFileItk(const std::filesystem::path& path, const LoadOptions& options);
// 1 or 2 for a .nii or .nii.gz file (the name's case aside) with a NIfTI-1
// (348-byte) or NIfTI-2 (540-byte) header, 0 for any other file.
int niftiFileVersion(const std::filesystem::path& path);
// True for the files readWithNiftiLib takes: .nii and .nii.gz files with a
// NIfTI-1 or NIfTI-2 header.
bool readsWithNiftiLib(const std::filesystem::path& path);
// libnifti2, without ITK (NiftiRead.cpp): a NIfTI-2 file (ITK 5.2 reads
// NIfTI-1 only), or a NIfTI-1 file as readImageFileItk reads it: the same
// RawVolume, value for value. Empty for the NIfTI-1 files where that is not
// sure, and for those that are refused (the error is then ITK's path's): the
// caller reads them with readImageFileItk. Never empty for NIfTI-2.
std::optional<RawVolume> readWithNiftiLib(const std::filesystem::path& path, const LoadOptions& options);
// Loads libnifti2 (for `isohex batch`, before its jobs fork); false if it is missing.
bool loadNiftiLib();
// ITK: a folder holding one or more DICOM series.
RawVolume readDicomFolderItk(const std::filesystem::path& dir, const LoadOptions& options);
// ITK: a folder of 2-D TIFF slices, stacked in natural file-name order.
RawVolume readTiffSlicesItk(const std::vector<std::filesystem::path>& files,
                            const LoadOptions& options);
// OpenEXR: a folder of single-channel float slices.
RawVolume readExrSlices(const std::vector<std::filesystem::path>& files,
                        const LoadOptions& options);

// ITK's Otsu threshold of a list of (finite) values.
double otsuThresholdItk(const std::vector<float>& values);
// The same from the 256-bin histogram of values in [vmin, vmax] that
// otsuThresholdItk fills (bin = min(255, int((v - vmin) * 256 / (vmax - vmin))));
// a caller streaming the scan fills it slab by slab.
inline constexpr int kOtsuBins = 256;
double otsuFromHistogramItk(const std::vector<std::uint64_t>& counts, double vmin, double vmax);

// File-name order where runs of digits compare by value ("s2" < "s10").
bool naturalLess(const std::string& a, const std::string& b);

}  // namespace isohex::imaging::detail

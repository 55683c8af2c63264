#pragma once
// Internal: checks of NIfTI, MetaImage and TIFF files that ITK's readers would
// read wrong without an exception (zero-filled, truncated, a process abort or
// an endless loop). They read the file's own header with zlib or libtiff, not
// ITK, and throw isohex::Error with what is wrong and how to fix it.
#include <cstdint>
#include <string>
#include <vector>

#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {

// NIfTI: throws if pixdim, the quaternion or the affine rows in use are not
// finite (ITK's reader aborts the process on them). Before ITK reads the header.
void checkNiftiOrientation(const std::string& file);
// NIfTI: throws if the file (for .nii.gz its uncompressed stream) is shorter
// than vox_offset plus `dataBytes`, or its compressed data is damaged.
void checkNiftiDataSize(const std::string& file, std::uint64_t dataBytes, bool gzipped);
// NIfTI: puts NaN back into `values` where the file's float voxels of volume
// `frame` of `frames`, component `comp`, are not finite (ITK's reader zeroes them).
void restoreNiftiNonFinite(const std::string& file, std::vector<float>& values, std::int64_t frame,
                           std::int64_t frames, int comp);

// MetaImage: throws on header fields MetaIO mishandles (NDims, DimSize, ASCII
// data, missing LIST or pattern files, HeaderSize). Before MetaIO reads it.
void checkMetaImageHeader(const std::string& file);
// MetaImage: throws if the voxel data (LOCAL or one data file) is missing,
// shorter than `dataBytes`, or compressed and damaged or of the wrong size.
void checkMetaImageSize(const std::string& file, std::uint64_t dataBytes);

// TIFF: throws if a page's strip or tile ends past the end of the file, or
// libtiff reports an error walking the pages. Before ITK reads it.
void checkTiffLayout(const std::string& file);

// The message for voxel data shorter than the header says.
[[noreturn]] inline void throwTruncated(const std::string& file, std::uint64_t need, std::uint64_t have,
                                        const char* what) {
    throw Error(file + ": the voxel data is truncated: the header promises " + std::to_string(need) + " " +
                what + " but the file has " + std::to_string(have) + ". Copy or export the file again.");
}

}  // namespace isohex::imaging::detail

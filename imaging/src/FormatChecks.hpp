#pragma once
// Internal: checks of NIfTI, NRRD, MetaImage and TIFF files that ITK's readers would
// read wrong without an exception (zero-filled, truncated, a process abort or
// an endless loop). They read the file's own header with zlib or libtiff, not
// ITK, and throw isohex::Error with what is wrong and how to fix it.
#include <cstdint>
#include <string>
#include <vector>

#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {

// NIfTI: 1 or 2 for a NIfTI-1 or NIfTI-2 header (sizeof_hdr 348 or 540, in
// either byte order, the file gzipped or not), 0 for anything else.
int niftiVersion(const std::string& file);
// NIfTI-1: true for a 348-byte header whose magic is "n+1" (one file of
// header and voxels); false for "ni1" (a .hdr's), Analyze 7.5 and the rest.
bool niftiOneFileMagic(const std::string& file);
// NIfTI: throws if pixdim, the quaternion or the affine rows in use are not
// finite (ITK's reader aborts the process on them). Before ITK reads the header.
void checkNiftiOrientation(const std::string& file);
// NIfTI: throws on header fields nifti1_io reads past silently (datatype and
// bitpix disagreeing, vox_offset not a number, negative or inside the header,
// a zero pixdim without an sform) and, for a .hdr/.img pair (`dataFile` not
// `file`), a data file that is missing or not a regular file.
void checkNiftiHeaderFields(const std::string& file, const std::string& dataFile);
// NIfTI: throws if the data (`dataFile`: the file itself, or a pair's .img;
// for .nii.gz its uncompressed stream) is shorter or longer than vox_offset
// plus `dataBytes`, or its compressed data is damaged.
void checkNiftiDataSize(const std::string& file, const std::string& dataFile, std::uint64_t dataBytes, bool gzipped);
// NIfTI: the bytes per voxel of the header's datatype when it is a scalar
// integer type, else 0. ITK reports such a file with scl_slope/scl_inter as
// float voxels, so the size of its data on disk is counted from this.
int niftiIntegerBytes(const std::string& file);
// NIfTI: puts NaN back into `values` where the file's float voxels of volume
// `frame` of `frames`, component `comp`, are not finite (ITK's reader zeroes them).
void restoreNiftiNonFinite(const std::string& file, std::vector<float>& values, std::int64_t frame,
                           std::int64_t frames, int comp);
// NIfTI-1: whether any float voxel of the file (every volume and component)
// is NaN or infinite; false for other data types and unreadable files.
bool niftiHasNonFinite(const std::string& file);

// MetaImage: throws on header fields MetaIO mishandles (NDims, DimSize, ASCII
// data, no ElementDataFile, HeaderSize) and on data files that are missing,
// not regular files, or (unless `allowDataOutside`) outside the header's
// folder. Before MetaIO reads it.
void checkMetaImageHeader(const std::string& file, bool allowDataOutside);

// NRRD: throws on a byte skip below -1 or a negative line skip, and on data
// files (one, a LIST, a pattern) that are missing, not regular files, or
// (unless `allowDataOutside`) outside the header's folder. Before ITK reads it.
void checkNrrdHeader(const std::string& file, bool allowDataOutside);
// MetaImage: throws if the voxel data (LOCAL or one data file) is missing,
// shorter than `dataBytes`, or compressed and damaged or of the wrong size.
void checkMetaImageSize(const std::string& file, std::uint64_t dataBytes);

// TIFF: throws if a page's strip or tile ends past the end of the file, or
// libtiff reports an error walking the pages. Before ITK reads it.
void checkTiffLayout(const std::string& file);

// True if a header's file-name pattern holds one integer conversion (%d,
// %03d, %i) and nothing else printf would read an argument for, and is at
// most 1000 characters (NRRD and MetaImage patterns are handed to printf).
inline bool isOneIntegerPattern(const std::string& pattern) {
    const auto percent = pattern.find('%');
    if (percent == std::string::npos || pattern.size() > 1000) return false;
    std::size_t at = percent + 1;
    while (at < pattern.size() && pattern[at] >= '0' && pattern[at] <= '9') ++at;
    return at < pattern.size() && (pattern[at] == 'd' || pattern[at] == 'i') && pattern.find('%', at) == std::string::npos;
}

// The message for voxel data shorter than the header says.
[[noreturn]] inline void throwTruncated(const std::string& file, std::uint64_t need, std::uint64_t have,
                                        const char* what) {
    throw Error(file + ": the voxel data is truncated: the header promises " + std::to_string(need) + " " +
                what + " but the file has " + std::to_string(have) + ". Copy or export the file again.");
}

}  // namespace isohex::imaging::detail

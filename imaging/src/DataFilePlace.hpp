#pragma once
// Internal: where a header (NRRD .nhdr, MetaImage .mhd, a LIST of files, a
// file pattern) may point its voxel data. A header is text anyone can write:
// followed blindly, '../../etc/passwd', '/dev/urandom' or the header itself
// were read as voxels and meshed. No ITK here.
#include <filesystem>
#include <string>

namespace isohex::imaging::detail {

// The file `named` (as the header writes it: relative to the header's folder,
// or absolute) that the header `header` points its voxel data at. Throws
// isohex::Error naming the header, the data file and the fault unless it is
// an existing regular file other than the header itself, and (unless
// `allowOutside`) inside the header's folder or below it, symbolic links
// resolved. Returns its path as the readers will open it.
std::filesystem::path checkDataFilePlace(const std::string& header, const std::string& named, bool allowOutside);

}  // namespace isohex::imaging::detail

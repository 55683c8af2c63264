#pragma once
// Loading a scan reader's library ahead of time. The readers through ITK
// (with GDCM, libtiff) and OpenEXR are plugins loaded on first use
// (isohex/core/Plugin.hpp); `isohex batch` loads the ones its jobs need
// before it forks them, so every job's process inherits the libraries
// instead of loading them again.
#include <filesystem>

namespace isohex::imaging {

// Loads the plugin loadVolume will use for `input` (ITK for image files and
// DICOM or TIFF folders, OpenEXR for folders of .exr slices; nothing for .vdb
// files and triangle surfaces). For .nii and .nii.gz files libnifti2 as well
// as ITK: loadVolume reads them with libnifti2 but leaves some NIfTI-1 files
// to ITK, and Otsu's threshold is ITK's. Returns false if it cannot be
// loaded; the reason is left to loadVolume, which throws it for the job it
// concerns.
bool preloadReader(const std::filesystem::path& input);

}  // namespace isohex::imaging

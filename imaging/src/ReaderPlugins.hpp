#pragma once
// Internal: the scan readers whose libraries are loaded on first use
// (isohex/core/Plugin.hpp). ITK with GDCM and libtiff (src/Itk*.cpp,
// TiffChecks.cpp) is the plugin libisohex_itk.so, OpenEXR (ExrRead.cpp)
// libisohex_exr.so, Assimp (AssimpRead.cpp) libisohex_assimp.so; they link
// this library for the checks every reader shares. The scan readers'
// functions are those of RawVolume.hpp.
#include <filesystem>
#include <string>
#include <vector>

#include "RawVolume.hpp"
#include "isohex/imaging/Surface.hpp"

namespace isohex::imaging::detail {

struct ItkReaders {
    static constexpr int kAbi = 2;
    int abi;
    RawVolume (*readImageFile)(const std::filesystem::path& path, const LoadOptions& options);
    RawVolume (*readDicomFolder)(const std::filesystem::path& dir, const LoadOptions& options);
    RawVolume (*readTiffSlices)(const std::vector<std::filesystem::path>& files, const LoadOptions& options);
    double (*otsuThreshold)(const std::vector<float>& values);
    double (*otsuFromHistogram)(const std::vector<std::uint64_t>& counts, double vmin, double vmax);
};

struct ExrReader {
    static constexpr int kAbi = 1;
    int abi;
    RawVolume (*readSlices)(const std::vector<std::filesystem::path>& files, const LoadOptions& options);
};

struct SurfaceReader {
    static constexpr int kAbi = 1;
    int abi;
    // The triangles of `file` (or, for an OFF file, of `offText`, its text
    // without comments, when not null), corners with equal coordinates
    // welded; throws Error when Assimp cannot read it.
    TriangleSurface (*read)(const std::string& file, const std::string* offText);
};

// Loaded on the first call; throw Error (Plugin.hpp) when they cannot be.
const ItkReaders& itkReaders();
const ExrReader& exrReader();
const SurfaceReader& surfaceReader();

// In the plugins (their sources), named by the tables above.
TriangleSurface readAssimpSurface(const std::string& file, const std::string* offText);

}  // namespace isohex::imaging::detail

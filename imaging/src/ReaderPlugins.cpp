#include "ReaderPlugins.hpp"

#include <algorithm>
#include <cctype>
#include <string>
#include <system_error>

#include "isohex/core/Error.hpp"
#include "isohex/core/Plugin.hpp"
#include "isohex/imaging/ReaderPlugin.hpp"
#include "isohex/imaging/SurfaceVolume.hpp"

namespace isohex::imaging {

namespace detail {

const ItkReaders& itkReaders() {
    return plugin::load<ItkReaders>(
        "itk", "reads NIfTI, NRRD, MetaImage, TIFF and DICOM scans and finds Otsu's threshold with ITK");
}

const ExrReader& exrReader() { return plugin::load<ExrReader>("exr", "reads OpenEXR slices"); }

const SurfaceReader& surfaceReader() {
    return plugin::load<SurfaceReader>("assimp", "reads triangle surfaces (.stl, .obj, .ply, .off) with Assimp");
}

}  // namespace detail

bool preloadReader(const std::filesystem::path& input) {
    namespace fs = std::filesystem;
    auto lower = [](std::string s) {
        std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
        return s;
    };
    try {
        std::error_code ec;
        if (fs::is_directory(input, ec)) {
            for (const auto& e : fs::directory_iterator(input, ec))
                if (lower(e.path().extension().string()) == ".exr") {
                    detail::exrReader();
                    return true;
                }
            detail::itkReaders();
            return true;
        }
        if (lower(input.extension().string()) == ".vdb") return true;
        if (isSurfaceFile(input.string())) {
            detail::surfaceReader();
            return true;
        }
        // NIfTI: libnifti2, and ITK too, which reads the NIfTI-1 files
        // libnifti2 cannot read as ITK does and finds Otsu's threshold.
        if (detail::readsWithNiftiLib(input)) detail::loadNiftiLib();
        detail::itkReaders();
        return true;
    } catch (const Error&) {
        return false;
    }
}

}  // namespace isohex::imaging

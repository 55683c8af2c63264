// Plugin libisohex_itk.so: the readers through ITK, GDCM and libtiff (src/Itk*.cpp).
#include "HeldStderr.hpp"
#include "ReaderPlugins.hpp"

namespace {

using namespace isohex::imaging::detail;

// What the libraries print on stderr while a reader runs is held back
// (HeldStderr.hpp): replayed when the read succeeds, dropped when it throws.
template <class Source>
RawVolume heldRead(RawVolume (*read)(const Source&, const isohex::imaging::LoadOptions&), const Source& source,
                   const isohex::imaging::LoadOptions& options) {
    HeldStderr held;
    RawVolume volume = read(source, options);
    held.replay();
    return volume;
}

RawVolume readImageFile(const std::filesystem::path& path, const isohex::imaging::LoadOptions& options) {
    return heldRead(readImageFileItk, path, options);
}
RawVolume readDicomFolder(const std::filesystem::path& dir, const isohex::imaging::LoadOptions& options) {
    return heldRead(readDicomFolderItk, dir, options);
}
RawVolume readTiffSlices(const std::vector<std::filesystem::path>& files, const isohex::imaging::LoadOptions& options) {
    return heldRead(readTiffSlicesItk, files, options);
}

const ItkReaders kApi{ItkReaders::kAbi, readImageFile, readDicomFolder, readTiffSlices, otsuThresholdItk,
                     otsuFromHistogramItk};

}  // namespace

extern "C" const void* isohex_plugin_api() { return &kApi; }

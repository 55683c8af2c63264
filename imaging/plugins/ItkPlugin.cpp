// Plugin libisohex_itk.so: the readers through ITK, GDCM and libtiff (src/Itk*.cpp).
#include "ReaderPlugins.hpp"

namespace {

using namespace isohex::imaging::detail;

const ItkReaders kApi{ItkReaders::kAbi, readImageFileItk, readDicomFolderItk, readTiffSlicesItk, otsuThresholdItk};

}  // namespace

extern "C" const void* isohex_plugin_api() { return &kApi; }

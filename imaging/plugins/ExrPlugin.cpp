// Plugin libisohex_exr.so: OpenEXR slices (src/ExrRead.cpp).
#include "ReaderPlugins.hpp"

namespace {

using namespace isohex::imaging::detail;

const ExrReader kApi{ExrReader::kAbi, readExrSlices};

}  // namespace

extern "C" const void* isohex_plugin_api() { return &kApi; }

// Plugin libisohex_assimp.so: triangle surfaces through Assimp (src/AssimpRead.cpp).
#include "ReaderPlugins.hpp"

namespace {

using namespace isohex::imaging::detail;

const SurfaceReader kApi{SurfaceReader::kAbi, readAssimpSurface};

}  // namespace

extern "C" const void* isohex_plugin_api() { return &kApi; }

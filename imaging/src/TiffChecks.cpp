// TIFF layout check before ITK's reader (see FormatChecks.hpp).
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <tiffio.h>

#include "FormatChecks.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {
namespace {

// libtiff's messages while checkTiffLayout runs (its handlers are
// process-wide; scans are loaded on one thread).
std::vector<std::string>* gTiffMessages = nullptr;

void keepTiffMessage(const char* module, const char* fmt, va_list ap, bool warning) {
    char text[512];
    std::vsnprintf(text, sizeof text, fmt, ap);
    const std::string m = std::string(module ? module : "libtiff") + ": " + text;
    // Warnings are mostly about tags libtiff does not know (GeoTIFF, vendors'
    // own); a warning that a tag could not be read means the file ends early.
    if (gTiffMessages && (!warning || m.find("IO error") != std::string::npos)) gTiffMessages->push_back(m);
}
extern "C" void tiffError(const char* module, const char* fmt, va_list ap) { keepTiffMessage(module, fmt, ap, false); }
extern "C" void tiffWarning(const char* module, const char* fmt, va_list ap) { keepTiffMessage(module, fmt, ap, true); }

}  // namespace

// A TIFF file cut short loses its last pages without a word: ITK reads the
// pages libtiff can find (libtiff only prints "Failed to read directory"),
// so a multi-page scan cut short would be meshed with fewer slices, or end
// in a misleading message about constant voxels. Before ITK reads it, libtiff walks every page's
// directory here and each strip or tile must end inside the file; any
// libtiff error on the way (or a tag it could not read) refuses the file.
void checkTiffLayout(const std::string& file) {
    std::vector<std::string> messages;
    gTiffMessages = &messages;
    const TIFFErrorHandler oldError = TIFFSetErrorHandler(tiffError);
    const TIFFErrorHandler oldWarning = TIFFSetWarningHandler(tiffWarning);
    struct Restore {
        TIFFErrorHandler e, w;
        ~Restore() {
            TIFFSetErrorHandler(e);
            TIFFSetWarningHandler(w);
            gTiffMessages = nullptr;
        }
    } restore{oldError, oldWarning};
    std::error_code ec;
    const std::uint64_t size = std::filesystem::file_size(file, ec);
    if (ec) return;
    TIFF* tif = TIFFOpen(file.c_str(), "r");
    if (!tif) return;  // ITK says what it makes of a file libtiff cannot open
    std::string problem;
    int page = 0;
    do {
        ++page;
        const bool tiled = TIFFIsTiled(tif);
        const std::uint32_t pieces = tiled ? TIFFNumberOfTiles(tif) : TIFFNumberOfStrips(tif);
        for (std::uint32_t i = 0; i < pieces && problem.empty(); ++i) {
            const std::uint64_t offset = TIFFGetStrileOffset(tif, i), bytes = TIFFGetStrileByteCount(tif, i);
            if (offset > size || bytes > size - offset)
                problem = "page " + std::to_string(page) + "'s " + (tiled ? "tile " : "strip ") + std::to_string(i) +
                          " ends at byte " + std::to_string(offset + bytes) + " of a file of " + std::to_string(size);
        }
    } while (problem.empty() && messages.empty() && TIFFReadDirectory(tif));
    TIFFClose(tif);
    if (problem.empty() && !messages.empty()) problem = boundedMessage(messages.front(), 500);
    if (!problem.empty())
        throw Error(file + ": the TIFF file is damaged or truncated (" + problem + "); export it again.");
}

}  // namespace isohex::imaging::detail

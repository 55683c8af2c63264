// Plugin libisohex_itk.so: the readers through ITK, GDCM and libtiff (src/Itk*.cpp).
#include <cstdio>

#include <unistd.h>

#include "ReaderPlugins.hpp"

namespace {

using namespace isohex::imaging::detail;

// What the libraries print on stderr while a reader runs (niftilib's
// "** ERROR: nifti_convert_nhdr2nim", MetaIO's "DimSize required", teem's
// "[nrrd] ...") is held back: replayed when the read succeeds, so a warning
// still reaches the user, and dropped when it throws, because isohex's own
// one-line error then names the file and what is wrong with it.
class HeldStderr {
public:
    HeldStderr() {
        std::fflush(stderr);
        held_ = std::tmpfile();
        if (!held_) return;
        saved_ = dup(2);
        if (saved_ < 0 || dup2(fileno(held_), 2) < 0) restore();
    }
    HeldStderr(const HeldStderr&) = delete;
    HeldStderr& operator=(const HeldStderr&) = delete;
    ~HeldStderr() { restore(); }

    // Restores stderr and writes to it what was held.
    void replay() {
        if (!held_ || saved_ < 0) return;
        std::fflush(stderr);
        dup2(saved_, 2);
        std::rewind(held_);
        char buf[4096];
        for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, held_)) > 0;)
            if (write(2, buf, n) < 0) break;
        restore();
    }

private:
    void restore() {
        if (saved_ >= 0) {
            std::fflush(stderr);
            dup2(saved_, 2);
            close(saved_);
            saved_ = -1;
        }
        if (held_) std::fclose(held_);
        held_ = nullptr;
    }

    std::FILE* held_ = nullptr;
    int saved_ = -1;
};

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

#pragma once
// Internal: what the scan readers' libraries print on stderr while they read
// (niftilib's "** ERROR: nifti_convert_nhdr2nim", MetaIO's "DimSize
// required", teem's "[nrrd] ...") held back: replayed when the read
// succeeds, so a warning still reaches the user, and dropped when it fails,
// because isohex's own one-line error then names the file and what is wrong
// with it. Used by the ITK plugin (plugins/ItkPlugin.cpp) and NiftiRead.cpp.
#include <cstdio>

#include <unistd.h>

namespace isohex::imaging::detail {

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
    // Restores stderr, dropping what was held unless replay() came first.
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

}  // namespace isohex::imaging::detail

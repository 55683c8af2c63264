#pragma once
// Write-to-temporary-then-rename, so readers never see a half-written file and
// an existing file survives a failed write.
#include <functional>
#include <string>

#include "isohex/core/DiskFullError.hpp"

namespace isohex::io {

// Calls `produce(tmpPath)` with a fresh temporary path in the folder of
// `path`, then renames it to `path`. If produce throws, the temporary is
// removed and the exception propagates; an isohex::Error thrown while the
// disk is full (4 MB or less free) becomes a DiskFullError. `path` is
// untouched. Without
// `overwrite`, an existing `path` is refused before anything is written.
void writeAtomically(const std::string& path, bool overwrite,
                     const std::function<void(const std::string& tmpPath)>& produce);

// writeAtomically of `text` as the whole file; errors name `path` and the
// system's reason.
void writeTextAtomically(const std::string& path, bool overwrite, const std::string& text);

// How every temporary that process `pid` writes for `path` begins (its file
// name, in the folder of `path`): ".<stem>.tmp<pid>_". A process that
// outlives a writer it forked removes what the writer left with it.
std::string temporaryPrefix(const std::string& path, long pid);

// Installs handlers for SIGINT, SIGTERM and SIGHUP that remove the temporary
// files of writes in progress, then let the signal end the process as it
// would have (for programs: call once at start-up).
void removeTemporariesOnSignal();

// A finished file the signal handler also removes until released: the
// outputs a job has written while its later ones are still being made, so an
// interrupted job leaves none of them (a rerun redoes it instead of refusing
// the files it left). Returns a handle for releaseOnSignal (-1: not tracked).
int removeOnSignal(const std::string& path);
void releaseOnSignal(int handle);

}  // namespace isohex::io

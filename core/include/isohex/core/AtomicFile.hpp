#pragma once
// Write-to-temporary-then-rename, so readers never see a half-written file and
// an existing file survives a failed write.
#include <functional>
#include <string>

namespace isohex::io {

// Calls `produce(tmpPath)` with a fresh temporary path in the folder of
// `path`, then renames it to `path`. If produce throws, the temporary is
// removed and the exception propagates; `path` is untouched. Without
// `overwrite`, an existing `path` is refused before anything is written.
void writeAtomically(const std::string& path, bool overwrite,
                     const std::function<void(const std::string& tmpPath)>& produce);

}  // namespace isohex::io

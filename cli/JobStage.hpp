#pragma once
// Where a job is: the stage it has begun and the file it is reading. Stage
// reporting (cli/Progress.hpp) and the commands that read files themselves
// record it here; an isolated job's child keeps it in a page shared with the
// parent (cli/Isolate.hpp), so the parent can say where a child that crashed
// was. The tests' fault injection hooks in here too.
#include <string>
#include <string_view>

namespace isohex::cli {

// Called when a stage begins (ProgressSink::begin): inside an isolated job
// it records the stage for the parent's message. It also serves the tests'
// fault injection: with ISOHEX_TEST_CRASH=<stage> the process raises SIGSEGV
// when that stage begins (ISOHEX_TEST_CRASH=<stage>:kill raises SIGKILL);
// a suffix @<text> limits it to jobs whose input path (or the path
// nowReading names) contains the text. The handling of a crashing library
// is then tested without depending on one library's bug.
void stageBegins(std::string_view stage);

// A command that reads its files itself says which one it is reading: the
// "load" stage begins, a crash names that file, and ISOHEX_TEST_CRASH's
// @<text> is matched against it.
void nowReading(const std::string& file);

// The record an isolated job's child writes and its parent reads: a page
// shared between them (MAP_SHARED survives the child's crash; a pipe
// message might not have been sent).
struct StageSlot {
    char stage[64];
    char file[1024];  // the file being read, when it is not the job's input (insert-sheet's surfaces)
};

// The shared page (made once, before the first fork); nullptr if it cannot be mapped.
StageSlot* sharedStageSlot();
// The job now starting: its input, matched against ISOHEX_TEST_CRASH's @<text>.
void jobStarts(const std::string& input);
// In an isolated job's child: record the stages in `slot` from now on.
void recordStagesIn(StageSlot* slot);

}  // namespace isohex::cli

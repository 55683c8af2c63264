#pragma once
// Internal: checks of DICOM files and series that GDCM and ITK would read
// wrong without an exception (a cut file padded, a damaged slice left out of
// its series, slices stacked at one spacing that do not have one). They throw
// isohex::Error naming the file and what to do. No GDCM or ITK types here.
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "isohex/imaging/Volume.hpp"

namespace isohex::imaging::detail {

// Keeps GDCM's warnings and errors (process-wide streams; scans are loaded
// on one thread) off the console while it lives: where they matter, isohex's
// own message says what was wrong.
class QuietGdcm {
public:
    QuietGdcm();
    ~QuietGdcm();
    // True if GDCM wrote `text` while this object lived.
    bool said(const std::string& text) const { return sink_.str().find(text) != std::string::npos; }
    QuietGdcm(const QuietGdcm&) = delete;
    QuietGdcm& operator=(const QuietGdcm&) = delete;

private:
    std::ostringstream sink_;
    std::ostream& warnings_;
    std::ostream& errors_;
};

// The end of the message for a DICOM file GDCM cannot read to the end.
extern const char* const kDicomUnreadable;

// A file marked "DICM": throws if it ends inside an element before its Pixel
// Data (Debian's GDCM aborts the process on such a file). Before GDCM reads it.
void checkDicomStructure(const std::string& file);

// One DICOM file read on its own (a multi-frame file): throws if GDCM cannot
// read it, or its Pixel Data ends past the end of the file or is not the
// size its Rows, Columns, frames and BitsAllocated give.
void checkDicomLength(const std::string& file);

// Throws if the slices' positions along their normal do not step evenly
// (a missing slice, or variable spacing) or two lie at one position.
// Slices without the tags pass.
void checkSliceSpacing(const std::string& folder, const std::vector<std::string>& files);

// Throws for a file whose Image Orientation (Patient) is not two
// perpendicular unit vectors or whose Pixel Spacing is not positive (ITK
// substitutes identity and 1 mm). Files without the tags pass.
void checkDicomGeometryTags(const std::vector<std::string>& files);

// Throws if a file of `others` (the folder's other series) shares the first
// chosen file's series UID and orientation but not its rows and columns.
void checkSeriesSliceSize(const std::vector<std::string>& chosen, const std::vector<std::string>& others);

// What GDCM makes of one file of a DICOM folder, read before its series scan.
struct DicomFileScan {
    bool marked = false;  // "DICM" after the 128-byte preamble
    bool named = false;   // not marked, but named .dcm or .dicom
    bool readable = false;
    bool imageWithoutPixels = false;  // an image storage class, but no Pixel Data
    std::string pixelFault;           // why its Pixel Data cannot be read as declared (cut short, wrong size), or empty
};

// Reads every file of the folder with GDCM, one at a time, each named through
// `options.reading` first (see the definition for why).
std::map<std::filesystem::path, DicomFileScan> scanDicomFolder(const std::filesystem::path& dir,
                                                             const LoadOptions& options);

// Throws for a file no series lists that says it is DICOM but GDCM cannot
// read, or is an image without pixel data; other unlisted files pass.
void checkUnlistedDicomFiles(const std::map<std::filesystem::path, DicomFileScan>& scans,
                             const std::set<std::filesystem::path>& listed);

}  // namespace isohex::imaging::detail

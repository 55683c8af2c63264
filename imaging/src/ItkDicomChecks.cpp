// DICOM checks around GDCM's and ITK's readers (see DicomChecks.hpp).
#include "DicomChecks.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <locale>

#include <gdcmMediaStorage.h>
#include <gdcmReader.h>
#include <gdcmScanner.h>
#include <gdcmTrace.h>
#include <itkVector.h>

#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {

QuietGdcm::QuietGdcm() : warnings_(gdcm::Trace::GetWarningStream()), errors_(gdcm::Trace::GetErrorStream()) {
    gdcm::Trace::SetWarningStream(sink_);
    gdcm::Trace::SetErrorStream(sink_);
}

QuietGdcm::~QuietGdcm() {
    gdcm::Trace::SetWarningStream(warnings_);
    gdcm::Trace::SetErrorStream(errors_);
}

namespace {
// A DICOM file cut short was read in part: GDCM keeps the Pixel Data's
// declared length, pads what is missing (it only prints "Incomplete Pixel
// Data found" to the console) and ITK meshed the padding. GDCM gives where
// the Pixel Data's value starts in the file (reading up to it with the value
// skipped) and its declared length (a full read); the value must end inside
// the file. Only Pixel Data is checked: GDCM's sums over a whole data set
// are of the file as it would write it again (a preamble it adds, VRs it
// fixes), which is not the file on disk. A deflated data set is exempt (its
// positions are in the inflated stream; one cut short fails GDCM's read).
//
// Returns what is wrong, or nothing; `full` has read the whole file, and
// `quiet` has kept GDCM's warnings of that read alone.
std::string dicomPixelDataCut(const std::string& file, const gdcm::Reader& full, const QuietGdcm& quiet) {
    std::error_code ec;
    const std::uint64_t size = std::filesystem::file_size(file, ec);
    if (ec || full.GetFile().GetHeader().GetDataSetTransferSyntax().IsEncoded()) return {};
    const gdcm::Tag pixelData(0x7fe0, 0x0010);
    const gdcm::DataSet& ds = full.GetFile().GetDataSet();
    if (!ds.FindDataElement(pixelData)) return {};
    const gdcm::DataElement& pd = ds.GetDataElement(pixelData);
    std::uint64_t length = 0;
    if (!pd.GetVL().IsUndefined()) length = std::uint64_t(pd.GetVL());
    else if (const gdcm::SequenceOfFragments* f = pd.GetSequenceOfFragments()) length = std::uint64_t(f->ComputeLength());
    else return {};
    gdcm::Reader upTo;
    upTo.SetFileName(file.c_str());
    if (!upTo.ReadUpToTag(pixelData, {pixelData})) return {};
    const std::uint64_t start = upTo.GetStreamCurrentPosition();
    // A read that ran to the end of the file did not stop at the Pixel Data
    // (GDCM's full read copes with a data set in another VR than the meta
    // header says, this one does not); then only GDCM's own warning tells.
    const bool cut = start < size ? length > size - start : quiet.said("Incomplete Pixel Data");
    if (!cut) return {};
    return file + ": the DICOM file is truncated (its pixel data starts at byte " + std::to_string(start) +
           " and declares " + std::to_string(length) + " bytes, the file has " + std::to_string(size) +
           "); copy or export it again.";
}

// The numbers of a DICOM decimal-string value (backslash-separated); empty if any
// is not a number.
std::vector<double> dicomNumbers(const char* value) {
    std::vector<double> out;
    if (!value) return out;
    std::istringstream in(value);
    in.imbue(std::locale::classic());
    std::string piece;
    while (std::getline(in, piece, '\\')) {
        std::istringstream one(piece);
        one.imbue(std::locale::classic());
        double x = 0;
        if (!(one >> x) || !std::isfinite(x)) return {};
        out.push_back(x);
    }
    return out;
}

}  // namespace

const char* const kDicomUnreadable =
    ": the DICOM file is damaged or truncated (GDCM cannot read its data set to the end); copy or export it again.";

// The check above for one DICOM file read on its own (a multi-frame file).
void checkDicomLength(const std::string& file) {
    QuietGdcm quiet;  // its "Incomplete Pixel Data" warning would only repeat ours
    gdcm::Reader full;
    full.SetFileName(file.c_str());
    if (!full.Read()) throw Error(file + kDicomUnreadable);  // ITK read a deflated data set cut short
    const std::string cut = dicomPixelDataCut(file, full, quiet);
    if (!cut.empty()) throw Error(cut);
}

// ITK stacks a series' slices at one spacing (from the first and last
// positions), so a slice missing from the folder (a transfer cut short, or a
// file GDCM could not parse and left out of the series) or a protocol with
// variable spacing was meshed with every slice after the gap in the wrong
// place, without a word. The slices' Image Position (Patient) along their
// normal (from Image Orientation (Patient)) must step evenly, within 10% of
// the median step plus 0.1 (mm; positions are often rounded to 0.1 mm).
// Slices without those tags are left to ITK.
void checkSliceSpacing(const std::string& folder, const std::vector<std::string>& files) {
    const gdcm::Tag position(0x0020, 0x0032), orientation(0x0020, 0x0037);
    gdcm::Scanner scanner;
    scanner.AddTag(position);
    scanner.AddTag(orientation);
    {
        QuietGdcm quiet;
        if (!scanner.Scan(files)) return;
    }
    const std::vector<double> iop = dicomNumbers(scanner.GetValue(files.front().c_str(), orientation));
    if (iop.size() != 6) return;
    using V = itk::Vector<double, 3>;
    V normal = itk::CrossProduct(V(std::array<double, 3>{iop[0], iop[1], iop[2]}.data()),
                                 V(std::array<double, 3>{iop[3], iop[4], iop[5]}.data()));
    if (!(normal.GetNorm() > 0.5)) return;
    normal.Normalize();
    std::vector<double> along;
    for (const auto& f : files) {
        const std::vector<double> p = dicomNumbers(scanner.GetValue(f.c_str(), position));
        if (p.size() != 3) return;
        along.push_back(normal[0] * p[0] + normal[1] * p[1] + normal[2] * p[2]);
    }
    std::vector<double> steps;
    for (std::size_t i = 1; i < along.size(); ++i) steps.push_back(along[i] - along[i - 1]);
    // Slices at one position, or out of order (GDCM could not sort them, e.g.
    // two phases in one series): not a question of spacing; left as before.
    const bool up = steps.front() > 0;
    for (double step : steps)
        if (step == 0 || (step > 0) != up) return;
    std::vector<double> sorted = steps;
    std::nth_element(sorted.begin(), sorted.begin() + (sorted.size() - 1) / 2, sorted.end());
    const double median = sorted[(sorted.size() - 1) / 2];  // the lower middle of an even count
    // Positions are often written to 0.1 mm, so 0.1 on top of 10%.
    const double tolerance = 0.1 * std::abs(median) + 0.1;
    std::size_t shortest = 0, longest = 0, uneven = 0;
    for (std::size_t i = 0; i < steps.size(); ++i) {
        if (std::abs(steps[i] - median) > tolerance) ++uneven;
        if (std::abs(steps[i]) < std::abs(steps[shortest])) shortest = i;
        if (std::abs(steps[i]) > std::abs(steps[longest])) longest = i;
    }
    if (uneven == 0) return;
    auto between = [&](std::size_t i) {
        return std::filesystem::path(files[i]).filename().string() + " and " +
               std::filesystem::path(files[i + 1]).filename().string();
    };
    std::ostringstream m;
    m.precision(6);
    m << folder << ": the DICOM slices are not evenly spaced: along the slice normal the step between slices "
      << "goes from " << std::abs(steps[shortest]) << " (" << between(shortest) << ") to " << std::abs(steps[longest])
      << " (" << between(longest) << "); " << uneven << " of " << steps.size()
      << " steps differ from the median step, " << std::abs(median) << ", by more than 10% (+0.1). ";
    if (std::abs(steps[longest]) > 1.5 * std::abs(median))
        m << "A slice is probably missing between " << between(longest)
          << " (an incomplete transfer, or a damaged file GDCM left out of the series); copy or export the "
             "series again.";
    else
        m << "isohex needs one slice spacing; resample the series to even spacing first.";
    throw Error(m.str());
}

// Reads every file of the folder with GDCM before ITK's series scan does, one
// at a time and named through `reading` first: Debian's GDCM stops the process
// on an assertion for a file cut inside its header, and the scan reads the
// whole folder in one call, so the crash report could only name the folder.
std::map<std::filesystem::path, DicomFileScan> scanDicomFolder(const std::filesystem::path& dir,
                                                             const LoadOptions& options) {
    std::map<std::filesystem::path, DicomFileScan> out;
    std::error_code ec;
    std::vector<std::filesystem::path> files;
    for (const auto& entry : std::filesystem::directory_iterator(dir, ec))
        if (entry.is_regular_file(ec)) files.push_back(entry.path().lexically_normal());
    std::sort(files.begin(), files.end());
    for (const auto& file : files) {
        if (file.filename().string().rfind("._", 0) == 0) continue;  // macOS AppleDouble side files
        DicomFileScan& scan = out[file];
        char mark[4] = {0, 0, 0, 0};
        {
            std::ifstream in(file, std::ios::binary);
            scan.marked = in.seekg(128) && in.read(mark, 4) && std::memcmp(mark, "DICM", 4) == 0;
        }
        if (!scan.marked) {  // cut before the mark, or older files without a preamble
            std::string ext = file.extension().string();
            for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
            scan.named = ext == ".dcm" || ext == ".dicom";
        }
        if (options.reading) options.reading(file.string());
        QuietGdcm quiet;  // per file: dicomPixelDataCut looks for this read's warning
        gdcm::Reader reader;
        reader.SetFileName(file.c_str());
        scan.readable = reader.Read();
        if (!scan.readable) continue;
        const gdcm::DataSet& ds = reader.GetFile().GetDataSet();
        gdcm::MediaStorage storage;
        storage.SetFromFile(reader.GetFile());
        scan.imageWithoutPixels = gdcm::MediaStorage::IsImage(storage) && !ds.FindDataElement(gdcm::Tag(0x7fe0, 0x0010));
        scan.cut = dicomPixelDataCut(file.string(), reader, quiet);
    }
    if (options.reading) options.reading(dir.string());
    return out;
}

// GDCM's series scan leaves out, without a word, a file whose data set it
// cannot parse (a deflated file cut short, a damaged header) or that has no
// image left (a file cut before its Pixel Data), so a damaged first or last
// slice made the volume a slice shorter. A file no series lists is refused by
// name if it says it is DICOM (its mark, or a .dcm name) and GDCM cannot read
// it, or if it is of an image storage class but has no Pixel Data. Other
// files no series lists (a DICOMDIR, a report, notes, macOS's "._" side
// files) are left alone.
void checkUnlistedDicomFiles(const std::map<std::filesystem::path, DicomFileScan>& scans,
                             const std::set<std::filesystem::path>& listed) {
    for (const auto& [file, scan] : scans) {
        if (listed.count(file)) continue;
        if ((scan.marked || scan.named) && !scan.readable)
            throw Error(file.string() + ": this DICOM file in the series folder is damaged or truncated (GDCM "
                        "cannot read its data set), so it was left out of the series; copy or export the series "
                        "again, or remove the file if it is not part of the scan.");
        if (scan.marked && scan.imageWithoutPixels)
            throw Error(file.string() + ": this DICOM image file in the series folder has no pixel data (it is "
                        "probably truncated), so it was left out of the series; copy or export the series again, "
                        "or remove the file if it is not part of the scan.");
    }
}

}  // namespace isohex::imaging::detail

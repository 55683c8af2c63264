// DICOM checks around GDCM's and ITK's readers (see DicomChecks.hpp).
#include "DicomChecks.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <initializer_list>
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

// An unsigned short of the data set (Rows, BitsAllocated, ...), or -1.
long dicomUnsigned(const gdcm::DataSet& ds, std::uint16_t group, std::uint16_t element) {
    const gdcm::Tag tag(group, element);
    if (!ds.FindDataElement(tag)) return -1;
    const gdcm::ByteValue* bv = ds.GetDataElement(tag).GetByteValue();
    if (!bv || bv->GetLength() < 2) return -1;
    std::uint16_t v = 0;
    std::memcpy(&v, bv->GetPointer(), 2);  // little endian: the transfer syntaxes GDCM reads natively here
    return v;
}

// A text value of the data set (Number of Frames, ...), or "".
std::string dicomText(const gdcm::DataSet& ds, std::uint16_t group, std::uint16_t element) {
    const gdcm::Tag tag(group, element);
    if (!ds.FindDataElement(tag)) return {};
    const gdcm::ByteValue* bv = ds.GetDataElement(tag).GetByteValue();
    return bv ? std::string(bv->GetPointer(), bv->GetLength()) : std::string();
}

// Native (not encapsulated) Pixel Data must hold exactly Rows x Columns x
// Samples per Pixel x Number of Frames values of BitsAllocated bits (plus
// one pad byte to an even length): GDCM pads shorter data and ITK reads
// longer data with the wrong voxel size, both without a word. Returns what
// is wrong, or nothing.
std::string dicomPixelDataSize(const std::string& file, const gdcm::Reader& full) {
    const gdcm::File& f = full.GetFile();
    const gdcm::TransferSyntax ts = f.GetHeader().GetDataSetTransferSyntax();
    if (ts.IsEncapsulated() || ts.IsEncoded() || ts.GetSwapCode() == gdcm::SwapCode::BigEndian) return {};
    const gdcm::DataSet& ds = f.GetDataSet();
    const gdcm::Tag pixelData(0x7fe0, 0x0010);
    if (!ds.FindDataElement(pixelData)) return {};
    const gdcm::DataElement& pd = ds.GetDataElement(pixelData);
    if (pd.GetVL().IsUndefined() || !pd.GetByteValue()) return {};
    const long rows = dicomUnsigned(ds, 0x0028, 0x0010), columns = dicomUnsigned(ds, 0x0028, 0x0011);
    const long bits = dicomUnsigned(ds, 0x0028, 0x0100), stored = dicomUnsigned(ds, 0x0028, 0x0101);
    long samples = dicomUnsigned(ds, 0x0028, 0x0002);
    if (rows <= 0 || columns <= 0 || bits < 0) return {};  // GDCM refuses these itself
    if (samples <= 0) samples = 1;
    if (bits != 1 && bits != 8 && bits != 16 && bits != 32 && bits != 64)
        return file + ": the DICOM header's BitsAllocated is " + std::to_string(bits) +
               ", not a voxel size (8, 16, 32 or 64 bits); the file is damaged, export it again.";
    if (stored > bits)
        return file + ": the DICOM header's BitsStored (" + std::to_string(stored) + ") exceeds BitsAllocated (" +
               std::to_string(bits) + "); the header contradicts itself, export the file again.";
    long long frames = 1;
    if (const std::vector<double> n = dicomNumbers(dicomText(ds, 0x0028, 0x0008).c_str()); n.size() == 1 && n[0] >= 1)
        frames = static_cast<long long>(n[0]);
    const std::uint64_t need = (std::uint64_t(rows) * std::uint64_t(columns) * std::uint64_t(samples) *
                                    std::uint64_t(frames) * std::uint64_t(bits) + 7) / 8;
    const std::uint64_t have = std::uint64_t(pd.GetVL());
    if (have >= need && have <= need + 1) return {};
    std::ostringstream m;
    m << file << ": the DICOM Pixel Data holds " << have << " bytes but the header's " << rows << " rows x " << columns
      << " columns x " << frames << " frame(s) x " << samples << " sample(s) x BitsAllocated " << bits << " need " << need
      << (have < need ? ": the pixel data is short" : ": BitsAllocated or the image size does not describe the data")
      << "; the file is damaged, copy or export it again.";
    return m.str();
}

// Scans `files` for `tags`, GDCM's console kept quiet; false if the scan fails.
bool scanQuietly(gdcm::Scanner& scanner, const std::vector<std::string>& files, std::initializer_list<gdcm::Tag> tags) {
    for (const auto& tag : tags) scanner.AddTag(tag);
    QuietGdcm quiet;
    return scanner.Scan(files);
}

// The explicit-VR value representations with a 4-byte length.
bool longLengthVr(const char* vr) {
    static const char* const kLong[] = {"OB", "OD", "OF", "OL", "OV", "OW", "SQ", "SV", "UC", "UN", "UR", "UT", "UV"};
    return std::any_of(std::begin(kLong), std::end(kLong), [&](const char* v) { return std::memcmp(v, vr, 2) == 0; });
}

}  // namespace

// Debian's GDCM stops the process on an assertion (is.good() in its reader)
// when a DICOM file ends inside an element's tag, length or value before the
// Pixel Data. Before GDCM sees a file marked "DICM", its elements are walked
// here, lengths only: the meta group (explicit VR little endian), then the
// data set in its transfer syntax, into sequences and items, until the Pixel
// Data (whose own length dicomPixelDataCut checks). A deflated data set is
// left to GDCM (its reader fails cleanly on a cut stream).
void checkDicomStructure(const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    std::error_code ec;
    const std::uint64_t size = std::filesystem::file_size(file, ec);
    // n bytes at p (the caller keeps p + n within the file)
    auto bytesAt = [&](std::uint64_t p, std::size_t n) {
        std::string b(n, '\0');
        in.seekg(static_cast<std::streamoff>(p));
        in.read(b.data(), static_cast<std::streamsize>(n));
        return b;
    };
    if (ec || size < 132 || bytesAt(128, 4) != "DICM") return;
    std::uint64_t at = 132;
    bool meta = true, explicitVr = true, bigEndian = false;
    std::string syntax;
    auto u16 = [&](std::uint64_t p, bool big) {
        const std::string s = bytesAt(p, 2);
        const auto* b = reinterpret_cast<const unsigned char*>(s.data());
        return big ? std::uint16_t(b[0] << 8 | b[1]) : std::uint16_t(b[1] << 8 | b[0]);
    };
    auto u32 = [&](std::uint64_t p, bool big) {
        return big ? std::uint32_t(u16(p, true)) << 16 | u16(p + 2, true) : std::uint32_t(u16(p + 2, false)) << 16 | u16(p, false);
    };
    auto cut = [&](std::uint16_t g, std::uint16_t e, const std::string& what) {
        char tag[16];
        std::snprintf(tag, sizeof tag, "(%04x,%04x)", g, e);
        throw Error(file + ": the DICOM file is truncated inside its header: element " + tag + " at byte " +
                    std::to_string(at) + " " + what + ", and the file ends at byte " + std::to_string(size) +
                    "; copy or export it again.");
    };
    while (at < size) {
        if (at + 8 > size) cut(0, 0, "has no room for its tag and length");
        const bool big = !meta && bigEndian;
        const std::uint16_t group = u16(at, big), element = u16(at + 2, big);
        if (meta && group != 0x0002) {  // the data set starts: its transfer syntax applies from here
            meta = false;
            if (syntax == "1.2.840.10008.1.2.1.99") return;  // deflated
            explicitVr = syntax != "1.2.840.10008.1.2";
            bigEndian = syntax == "1.2.840.10008.1.2.2";
            continue;
        }
        if (group == 0x7fe0 && element == 0x0010) return;  // Pixel Data: checked on its own
        std::uint64_t header = 8, length = 0;
        if (group == 0xfffe) {  // items and delimiters: tag and length, no VR
            length = 0;  // walk into an item
        } else if (meta || explicitVr) {
            const std::string vr = bytesAt(at + 4, 2);
            if (longLengthVr(vr.c_str())) {
                if (at + 12 > size) cut(group, element, "has no room for its length");
                header = 12;
                length = u32(at + 8, big);
            } else {
                length = u16(at + 6, big);
            }
        } else {
            length = u32(at + 4, big);
        }
        if (length == 0xffffffffu) length = 0;  // undefined length (a sequence): walk into it
        if (at + header + length > size)
            cut(group, element, "declares " + std::to_string(length) + " bytes of value");
        if (meta && group == 0x0002 && element == 0x0010) {
            syntax = bytesAt(at + header, static_cast<std::size_t>(std::min<std::uint64_t>(length, 64)));
            while (!syntax.empty() && (syntax.back() == '\0' || syntax.back() == ' ')) syntax.pop_back();
        }
        at += header + length;
    }
    if (meta) {  // GDCM asserts on a file that ends inside or right after its meta group
        at = size;
        cut(0x0002, 0x0000, "(the file meta information) has no data set after it");
    }
}

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
    if (const std::string size = dicomPixelDataSize(file, full); !size.empty()) throw Error(size);
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
    if (!scanQuietly(scanner, files, {position, orientation})) return;
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
    // Two slices at one position (a slice twice, or two phases or echoes in
    // one series) were stacked as neighbours (GDCM's sort gives up and says
    // so on the console only): refused. Otherwise out of order (GDCM could
    // not sort them): not a question of spacing; left as before.
    std::vector<std::size_t> byPosition(along.size());
    for (std::size_t i = 0; i < along.size(); ++i) byPosition[i] = i;
    std::sort(byPosition.begin(), byPosition.end(), [&](std::size_t a, std::size_t b) { return along[a] < along[b]; });
    for (std::size_t k = 1; k < byPosition.size(); ++k) {
        const std::size_t i = byPosition[k - 1], j = byPosition[k];
        if (std::abs(along[j] - along[i]) >= 1e-4) continue;
        std::ostringstream m;
        m << folder << ": two DICOM slices, " << std::filesystem::path(files[std::min(i, j)]).filename().string()
          << " and " << std::filesystem::path(files[std::max(i, j)]).filename().string() << ", lie at the same position ("
          << along[i] << " along the slice normal): the series holds a slice twice, or two acquisitions (phases, "
          << "echoes). Remove the extra files, or pass a folder holding one acquisition.";
        throw Error(m.str());
    }
    const bool up = steps.front() > 0;
    for (double step : steps)
        if ((step > 0) != up) return;
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

// ITK puts identity axes in place of an Image Orientation (Patient) that is
// not two perpendicular unit vectors (all zero, say) and 1 mm in place of a
// Pixel Spacing of 0, without a word. Files without the tags pass (ITK's
// defaults are then all there is).
void checkDicomGeometryTags(const std::vector<std::string>& files) {
    const gdcm::Tag orientation(0x0020, 0x0037), spacing(0x0028, 0x0030);
    gdcm::Scanner scanner;
    if (!scanQuietly(scanner, files, {orientation, spacing})) return;
    for (const auto& f : files) {
        const char* iopText = scanner.GetValue(f.c_str(), orientation);
        const std::vector<double> iop = dicomNumbers(iopText);
        if (iopText && *iopText) {
            const double row = std::sqrt(iop.size() == 6 ? iop[0] * iop[0] + iop[1] * iop[1] + iop[2] * iop[2] : 0);
            const double column = std::sqrt(iop.size() == 6 ? iop[3] * iop[3] + iop[4] * iop[4] + iop[5] * iop[5] : 0);
            const double dot = iop.size() == 6 ? iop[0] * iop[3] + iop[1] * iop[4] + iop[2] * iop[5] : 1;
            if (std::abs(row - 1) > 1e-2 || std::abs(column - 1) > 1e-2 || std::abs(dot) > 1e-2)
                throw Error(f + ": the DICOM Image Orientation (Patient) is '" + iopText +
                            "', not two perpendicular unit vectors, so the slice's axes are unknown; the file is "
                            "damaged or anonymised wrongly, export it again.");
        }
        const char* psText = scanner.GetValue(f.c_str(), spacing);
        const std::vector<double> ps = dicomNumbers(psText);
        if (psText && *psText && (ps.size() != 2 || !(ps[0] > 0) || !(ps[1] > 0)))
            throw Error(f + ": the DICOM Pixel Spacing is '" + psText +
                        "', not two positive numbers, so the voxel size is unknown; the file is damaged, export it "
                        "again.");
    }
}

// GDCM's series scan (with series details) puts a slice of another size
// into a series of its own: one 32 x 32 slice among 24 x 24 ones left a gap
// reported as a missing slice. Slices of the chosen series' UID and
// orientation in other series must have its size.
void checkSeriesSliceSize(const std::vector<std::string>& chosen, const std::vector<std::string>& others) {
    const gdcm::Tag uid(0x0020, 0x000e), orientation(0x0020, 0x0037), rows(0x0028, 0x0010), columns(0x0028, 0x0011);
    gdcm::Scanner scanner;
    std::vector<std::string> all = chosen;
    all.insert(all.end(), others.begin(), others.end());
    if (chosen.empty() || !scanQuietly(scanner, all, {uid, orientation, rows, columns})) return;
    auto value = [&](const std::string& f, const gdcm::Tag& t) {
        const char* v = scanner.GetValue(f.c_str(), t);
        return v ? std::string(v) : std::string();
    };
    const std::string& first = chosen.front();
    const std::string size = value(first, columns) + " x " + value(first, rows);
    for (const auto& f : others) {
        if (value(f, uid) != value(first, uid) || value(f, orientation) != value(first, orientation)) continue;
        const std::string odd = value(f, columns) + " x " + value(f, rows);
        if (odd != size)
            throw Error(f + ": this slice is " + odd + " pixels but the other " + std::to_string(chosen.size()) +
                        " slices of its series are " + size + ": the slice size differs within the series. Remove "
                        "the odd file or export the series again.");
    }
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
        if (scan.marked) checkDicomStructure(file.string());  // before GDCM's reader asserts on it
        QuietGdcm quiet;  // per file: dicomPixelDataCut looks for this read's warning
        gdcm::Reader reader;
        reader.SetFileName(file.c_str());
        scan.readable = reader.Read();
        if (!scan.readable) continue;
        const gdcm::DataSet& ds = reader.GetFile().GetDataSet();
        gdcm::MediaStorage storage;
        storage.SetFromFile(reader.GetFile());
        scan.imageWithoutPixels = gdcm::MediaStorage::IsImage(storage) && !ds.FindDataElement(gdcm::Tag(0x7fe0, 0x0010));
        scan.pixelFault = dicomPixelDataCut(file.string(), reader, quiet);
        if (scan.pixelFault.empty()) scan.pixelFault = dicomPixelDataSize(file.string(), reader);
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

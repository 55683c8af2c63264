// A folder of DICOM files read with ITK into a RawVolume: every file read
// with GDCM first, the series listed and one chosen, its files checked, and
// its slices stacked (or one multi-frame file read as the image file it is).
#include <algorithm>
#include <map>
#include <set>
#include <sstream>

#include <itkGDCMImageIO.h>
#include <itkGDCMSeriesFileNames.h>
#include <itkImageSeriesReader.h>

#include "DicomChecks.hpp"
#include "ItkIo.hpp"
#include "RawChecks.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {
namespace {

// One series ITK found in the folder: its id (the SeriesInstanceUID followed
// by more fields) and its files, ordered along the slice normal.
struct Series {
    std::string id;
    std::vector<std::string> files;
};

// A DICOM folder on its way to a RawVolume; the phases below fill it in order.
struct DicomFolderRead {
    DicomFolderRead(const std::filesystem::path& d, const LoadOptions& o) : dir(d), options(o), folder(d.string()) {}

    const std::filesystem::path& dir;
    const LoadOptions& options;
    std::string folder;
    std::map<std::filesystem::path, DicomFileScan> scans;  // what GDCM made of each file
    std::vector<Series> series;
    const Series* chosen = nullptr;
};

// Reads every file with GDCM (scanDicomFolder), then lets ITK's series scan
// list the series. Series details split series that share a UID but differ in
// orientation or size; they must be set before the directory is scanned.
void listSeries(DicomFolderRead& r) {
    auto names = itk::GDCMSeriesFileNames::New();
    names->SetUseSeriesDetails(true);
    names->SetGlobalWarningDisplay(false);
    std::vector<std::string> ids;
    r.scans = scanDicomFolder(r.dir, r.options);
    try {
        QuietGdcm quiet;  // about files in the folder that are not DICOM
        names->SetDirectory(r.folder);
        ids = names->GetSeriesUIDs();
    } catch (const itk::ExceptionObject& e) {
        throw Error(r.folder + ": scanning for DICOM files failed (" + describe(e) + ").");
    }
    if (ids.empty()) {
        throw Error(r.folder + ": no DICOM series, .exr slices or .tif slices found in this folder. "
                    "Pass a folder of DICOM files (one series), a folder of slices, or an image file.");
    }
    QuietGdcm quiet;  // its sort's complaints (two slices at one position): checkSliceSpacing says what is wrong
    for (const auto& id : ids) r.series.push_back({id, names->GetFileNames(id)});
}

// The series one a line with their slice counts, for the messages that ask
// to choose one.
std::string listing(const std::vector<Series>& series) {
    std::ostringstream m;
    for (const auto& s : series) m << "\n  " << s.id << "  (" << s.files.size() << " slices)";
    return m.str();
}

// The series the series UID option names (the plain UID is accepted as a
// prefix of the detailed id), or else the one with the most slices; throws
// when none or several fit.
const Series* chooseSeries(const DicomFolderRead& r) {
    const std::string& uid = r.options.seriesUid;
    if (!uid.empty()) {
        std::vector<const Series*> hits;
        for (const auto& s : r.series)
            if (s.id == uid || s.id.rfind(uid, 0) == 0) hits.push_back(&s);
        if (hits.size() != 1) {
            throw Error(r.folder + ": series '" + uid + "' " +
                        (hits.empty() ? "is not in this folder" : "matches several series") +
                        ". The folder holds:" + listing(r.series) + "\nPass one of these as the series UID.");
        }
        return hits.front();
    }
    std::size_t most = 0;
    for (const auto& s : r.series) most = std::max(most, s.files.size());
    std::vector<const Series*> largest;
    for (const auto& s : r.series)
        if (s.files.size() == most) largest.push_back(&s);
    if (largest.size() > 1) {
        throw Error(r.folder + ": holds " + std::to_string(r.series.size()) +
                    " DICOM series and several have the most slices (" + std::to_string(most) +
                    "), so which to mesh is ambiguous:" + listing(r.series) +
                    "\nChoose one with the series UID option.");
    }
    return largest.front();
}

// Before ITK reads any file of the chosen series (its header read decodes the
// first slice): no damaged DICOM file was left out of every series, and, for
// a series of slices, each reads to the end and they are evenly spaced.
void checkSeriesFiles(const DicomFolderRead& r) {
    {
        std::set<std::filesystem::path> listed;
        for (const auto& sr : r.series)
            for (const auto& f : sr.files) listed.insert(std::filesystem::path(f).lexically_normal());
        checkUnlistedDicomFiles(r.scans, listed);
    }
    checkDicomGeometryTags(r.chosen->files);
    {
        std::vector<std::string> others;
        for (const auto& sr : r.series)
            if (&sr != r.chosen) others.insert(others.end(), sr.files.begin(), sr.files.end());
        checkSeriesSliceSize(r.chosen->files, others);
    }
    if (r.chosen->files.size() <= 1) return;
    for (const auto& f : r.chosen->files) {
        const auto it = r.scans.find(std::filesystem::path(f).lexically_normal());
        if (it == r.scans.end()) {
            checkDicomLength(f);  // not expected: the scan read the same folder
        } else {
            if (!it->second.readable) throw Error(f + kDicomUnreadable);
            if (!it->second.pixelFault.empty()) throw Error(it->second.pixelFault);
        }
    }
    checkSliceSpacing(r.folder, r.chosen->files);
}

// True when one file holds the whole volume: a multi-frame DICOM (enhanced
// CT or MR, and what ITK writes for a 3-D image). An unreadable file gives
// false; the header check of the reader that follows says why.
bool isMultiFrame(const std::string& file) {
    auto probe = itk::GDCMImageIO::New();
    try {
        QuietGdcm quiet;  // readImageFileItk checks the file
        probe->SetFileName(file);
        probe->ReadImageInformation();
        return probe->GetNumberOfDimensions() >= 3 && probe->GetDimensions(2) > 1;
    } catch (const itk::ExceptionObject&) {
        return false;
    }
}

// Stacks the chosen series' slices into one float volume; GDCMImageIO applies
// the rescale slope and intercept.
RawVolume readSlices(const DicomFolderRead& r) {
    const Series& chosen = *r.chosen;
    auto io = itk::GDCMImageIO::New();
    try {
        io->SetFileName(chosen.files.front());
        io->ReadImageInformation();
    } catch (const itk::ExceptionObject& e) {
        throw Error(chosen.files.front() + ": the DICOM header cannot be read (" + describe(e) +
                    "); the file is damaged, remove or replace it.");
    }
    if (io->GetNumberOfComponents() != 1) {
        throw Error(chosen.files.front() + ": DICOM images with " + std::to_string(io->GetNumberOfComponents()) +
                    " components per pixel (colour) are not supported; isohex needs greyscale.");
    }
    checkMemoryBudget(r.folder, sliceStackHeader(*io, chosen.files.size()), r.options.maxMemoryMB);

    auto reader = itk::ImageSeriesReader<FloatImage3>::New();
    reader->SetImageIO(io);
    reader->SetFileNames(chosen.files);  // ordered along the slice normal
    if (r.options.progress) r.options.progress("read", 0.0);
    try {
        reader->Update();
    } catch (const itk::ExceptionObject& e) {
        throw Error(r.folder + ": reading DICOM series " + chosen.id + " failed (" + describe(e) +
                    "). A slice is probably truncated or damaged.");
    }
    if (r.options.progress) r.options.progress("read", 1.0);
    FloatImage3::Pointer image = reader->GetOutput();
    RawVolume raw;
    raw.format = "DICOM";
    raw.pixelType = componentName(io->GetInternalComponentType());
    std::string uid;
    if (itk::ExposeMetaData<std::string>(io->GetMetaDataDictionary(), "0020|000e", uid)) {
        while (!uid.empty() && (uid.back() == ' ' || uid.back() == '\0')) uid.pop_back();
        raw.seriesUid = uid;
    } else {
        raw.seriesUid = chosen.id;
    }
    const auto size = image->GetLargestPossibleRegion().GetSize();
    for (int a = 0; a < 3; ++a) raw.dims[a] = static_cast<std::int64_t>(size[a]);
    copyGeometry(*image, raw);
    raw.values.assign(image->GetBufferPointer(), image->GetBufferPointer() + raw.count());
    return raw;
}

}  // namespace

RawVolume readDicomFolderItk(const std::filesystem::path& dir, const LoadOptions& options) {
    DicomFolderRead r(dir, options);
    listSeries(r);
    r.chosen = chooseSeries(r);
    checkSeriesFiles(r);
    // A single file is read as the image file it is if it holds all frames.
    if (r.chosen->files.size() == 1 && isMultiFrame(r.chosen->files.front()))
        return readImageFileItk(r.chosen->files.front(), options);
    if (r.chosen->files.size() < 2) {
        throw Error(r.folder + ": DICOM series " + r.chosen->id + " has a single slice; isohex needs "
                    "a 3-D volume (a series of at least two slices, or one multi-frame file).");
    }
    RawVolume raw = readSlices(r);
    checkGeometry(raw, r.folder);
    if (options.labels) convertToLabels(raw, r.folder, true);
    return raw;
}

}  // namespace isohex::imaging::detail

// One image file read with ITK (NIfTI, NRRD, MetaImage, TIFF, one DICOM
// file) into a RawVolume: isohex's own checks of the file before and after
// ITK reads its header, the choice of one scalar volume, and the voxel read.
#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <new>
#include <sstream>

#include <itkImageFileReader.h>
#include <itkImageIOFactory.h>

#include "DicomChecks.hpp"
#include "FormatChecks.hpp"
#include "ItkIo.hpp"
#include "RawChecks.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {
namespace {

// The formats whose files isohex checks itself around ITK's reader, told by
// the file's name (as ITK's readers pick gzip and the format).
enum class CheckedFormat { Other, Nifti, NiftiGz, NiftiPair, MetaImage, Nrrd, Tiff };

CheckedFormat checkedFormat(const std::filesystem::path& path) {
    std::string name = path.filename().string();
    for (auto& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    auto endsWith = [&](const std::string& e) {
        return name.size() >= e.size() && name.compare(name.size() - e.size(), e.size(), e) == 0;
    };
    if (endsWith(".nii")) return CheckedFormat::Nifti;
    if (endsWith(".nii.gz")) return CheckedFormat::NiftiGz;
    if (endsWith(".hdr") || endsWith(".img")) {  // NIfTI-1 or Analyze 7.5; a gzipped .img is left to ITK
        std::error_code ec;
        auto gz = path;
        gz.replace_extension(".img.gz");
        return std::filesystem::exists(gz, ec) ? CheckedFormat::Other : CheckedFormat::NiftiPair;
    }
    if (endsWith(".mha") || endsWith(".mhd")) return CheckedFormat::MetaImage;
    if (endsWith(".nrrd") || endsWith(".nhdr")) return CheckedFormat::Nrrd;
    if (endsWith(".tif") || endsWith(".tiff")) return CheckedFormat::Tiff;
    return CheckedFormat::Other;
}

// A NIfTI file's header and data: the file itself, or a pair's .hdr and .img.
std::pair<std::string, std::string> niftiFiles(const std::filesystem::path& path, CheckedFormat format) {
    if (format != CheckedFormat::NiftiPair) return {path.string(), path.string()};
    auto header = path, data = path;
    return {header.replace_extension(".hdr").string(), data.replace_extension(".img").string()};
}

// One image file on its way from its name to a RawVolume; the phases below
// fill it in order.
struct ImageFileRead {
    ImageFileRead(const std::filesystem::path& p, const LoadOptions& o)
        : path(p), options(o), file(p.string()), format(checkedFormat(p)) {}

    const std::filesystem::path& path;
    const LoadOptions& options;
    std::string file;
    CheckedFormat format = CheckedFormat::Other;
    itk::ImageIOBase::Pointer io;
    RawHeader header;
    itk::IOPixelEnum pixel{};
    itk::IOComponentEnum component{};
    std::int64_t frames = 1;   // volumes along the 4th dimension
    std::int64_t choices = 1;  // scalar volumes in the file: frames x components
    std::int64_t frame = 0;    // the chosen volume's frame and component
    int comp = 0;
};

// No ITK reader recognises the file: says so, with a hint when it is gzip
// data under a name without .gz (the readers pick gzip by the extension).
[[noreturn]] void refuseUnrecognised(const ImageFileRead& r) {
    unsigned char magic[2] = {0, 0};
    if (std::FILE* f = std::fopen(r.file.c_str(), "rb")) {
        const std::size_t n = std::fread(magic, 1, 2, f);
        std::fclose(f);
        if (n == 2 && magic[0] == 0x1f && magic[1] == 0x8b && r.path.extension() != ".gz")
            throw Error(r.file + ": the file is gzip-compressed but its name does not end in .gz; rename it to " +
                        r.path.filename().string() + ".gz or decompress it with gunzip.");
    }
    throw Error(r.file + ": not a readable image: no reader recognises its header (damaged "
                "file, or a format other than NIfTI, NRRD, MetaImage, TIFF, DICOM, OpenVDB). "
                "Check that the file is complete and its extension matches its content.");
}

// Finds ITK's reader for the file from its header.
void createIo(ImageFileRead& r) {
    {
        QuietGdcm quiet;  // the DICOM probe reads a file cut short and warns; checkDicomLength says why
        r.io = itk::ImageIOFactory::CreateImageIO(r.file.c_str(), itk::IOFileModeEnum::ReadMode);
    }
    if (!r.io) refuseUnrecognised(r);
    r.io->SetFileName(r.file);
}

// The checks that must come before ITK picks its reader, whose probes read
// the file: GDCM's asserts on a DICOM file cut inside its header, MetaIO's
// parses the MetaImage header.
void checkBeforeIo(const ImageFileRead& r) {
    checkDicomStructure(r.file);
    if (r.format == CheckedFormat::MetaImage) checkMetaImageHeader(r.file, r.options.allowDataOutside);
}

// The checks that must come before ITK reads the header: on what they refuse
// ITK's readers abort the process, loop for ever or pad without a word.
void checkBeforeHeader(const ImageFileRead& r) {
    if (r.format == CheckedFormat::Nrrd) checkNrrdHeader(r.file, r.options.allowDataOutside);
    if (r.format == CheckedFormat::Nifti || r.format == CheckedFormat::NiftiGz || r.format == CheckedFormat::NiftiPair) {
        const auto [header, data] = niftiFiles(r.path, r.format);
        checkNiftiHeaderFields(header, data);
        checkNiftiOrientation(header);
    }
    if (r.format == CheckedFormat::Tiff) checkTiffLayout(r.file);
    if (std::string(r.io->GetNameOfClass()) == "GDCMImageIO") {
        checkDicomLength(r.file);
        checkDicomGeometryTags({r.file});
    }
}

// Reads the header: sizes, components and the pixel and component types.
void readHeader(ImageFileRead& r) {
    try {
        r.io->ReadImageInformation();
    } catch (const itk::ExceptionObject& e) {
        if (describe(e).find("orthonormal") != std::string::npos)  // a sheared NIfTI sform and qform
            throwSheared(r.file, "the header's sform and qform give no orthonormal axes");
        throw Error(r.file + ": the " + formatName(*r.io) + " header cannot be read (" + describe(e) +
                    "). The file is damaged or not a " + formatName(*r.io) + " file; re-export it.");
    }
    r.header.dimensions = static_cast<int>(r.io->GetNumberOfDimensions());
    r.header.components = static_cast<int>(r.io->GetNumberOfComponents());
    r.header.bytesPerComponent = static_cast<int>(r.io->GetComponentSize());
    for (int a = 0; a < std::min(r.header.dimensions, 4); ++a) r.header.size[a] = r.io->GetDimensions(a);
    r.pixel = r.io->GetPixelType();
    r.component = r.io->GetComponentType();
}

// Refuses what isohex cannot mesh: complex or unknown pixels, and images
// that are not 3-D or 4-D.
void checkImageKind(const ImageFileRead& r) {
    if (r.pixel == itk::IOPixelEnum::COMPLEX || r.component == itk::IOComponentEnum::UNKNOWNCOMPONENTTYPE) {
        throw Error(r.file + ": unsupported pixel type '" + itk::ImageIOBase::GetPixelTypeAsString(r.pixel) +
                    "' of " + itk::ImageIOBase::GetComponentTypeAsString(r.component) +
                    "; isohex reads real-valued scalar images (integer or float). Convert it to "
                    "a scalar image first (e.g. the magnitude of complex data).");
    }
    // GDCM reads one slice file as 3-D, one slice thick: a 2-D image all the same.
    const bool oneSlice = std::string(r.io->GetNameOfClass()) == "GDCMImageIO" && r.header.size[2] == 1;
    if (r.header.dimensions < 3 || r.header.dimensions > 4 || oneSlice) {
        std::ostringstream m;
        m << r.file << ": a " << (oneSlice ? 2 : r.header.dimensions)
          << "-D image; isohex needs a 3-D volume (or a 4-D image with the volume index option).";
        if (r.header.dimensions == 2 || oneSlice) m << " For a stack of 2-D slices pass the folder holding them.";
        throw Error(m.str());
    }
}

// Counts the scalar volumes (frames x components) and checks that the volume
// index option picks one of them when there are several, and none otherwise.
void checkVolumeChoice(ImageFileRead& r) {
    r.frames = r.header.size[3];
    r.choices = r.frames * r.header.components;
    const std::int64_t index = r.options.volumeIndex;
    if (r.choices > 1) {
        std::ostringstream what;
        if (r.frames > 1 && r.header.components > 1)
            what << r.frames << " volumes of " << r.header.components << " components each";
        else if (r.frames > 1)
            what << "a 4-D image of " << r.frames << " volumes";
        else
            what << r.header.components << " components per voxel ("
                 << itk::ImageIOBase::GetPixelTypeAsString(r.pixel) << ")";
        if (index < 0) {
            throw Error(r.file + ": holds " + what.str() +
                        "; isohex meshes one scalar volume. Choose one with the volume index "
                        "option (0.." + std::to_string(r.choices - 1) + ").");
        }
        if (index >= r.choices) {
            throw Error(r.file + ": volume index " + std::to_string(index) + " is out of range; the file holds " +
                        what.str() + ", so use 0.." + std::to_string(r.choices - 1) + ".");
        }
    } else if (index > 0) {
        throw Error(r.file + ": volume index " + std::to_string(index) +
                    " does not exist: the file holds one scalar volume (index 0). Leave the option out.");
    }
}

// Before the bulk read: the memory budget, and the voxel data's size against
// the header where ITK would zero-fill or warn only.
void checkDataSize(const ImageFileRead& r) {
    RawHeader budget = r.header;  // a region: what is read of it
    for (int a = 0; a < 3 && !r.options.region.empty(); ++a)
        budget.size[a] = std::clamp<std::int64_t>(r.options.region.dim()[a], 1, r.header.size[a]);
    checkMemoryBudget(r.file, budget, r.options.maxMemoryMB);
    const auto bytes = static_cast<std::uint64_t>(r.io->GetImageSizeInBytes());
    if (r.format == CheckedFormat::Nifti || r.format == CheckedFormat::NiftiGz || r.format == CheckedFormat::NiftiPair) {
        const auto [header, data] = niftiFiles(r.path, r.format);
        // Integers with a scaling are reported as floats: the file holds the integers.
        const int integer = niftiIntegerBytes(header);
        const std::uint64_t fileBytes =
            integer > 0 ? static_cast<std::uint64_t>(r.io->GetImageSizeInComponents()) * std::uint64_t(integer) : bytes;
        checkNiftiDataSize(header, data, fileBytes, r.format == CheckedFormat::NiftiGz);
    }
    if (r.format == CheckedFormat::MetaImage) checkMetaImageSize(r.file, bytes);
}

// The 4-D region of the file's voxels to read: LoadOptions::region clipped to
// the file, every frame; the whole file without a region. Throws when the
// region misses the file.
VectorImage4::RegionType requestedRegion(const ImageFileRead& r) {
    VectorImage4::RegionType region;
    for (int a = 0; a < 4; ++a) {
        region.SetIndex(a, 0);
        region.SetSize(a, static_cast<itk::SizeValueType>(std::max<std::int64_t>(r.header.size[a], 1)));
    }
    const openvdb::CoordBBox& want = r.options.region;
    if (want.empty()) return region;
    for (int a = 0; a < 3; ++a) {
        const std::int64_t lo = std::max<std::int64_t>(want.min()[a], 0);
        const std::int64_t hi = std::min<std::int64_t>(want.max()[a], r.header.size[a] - 1);
        if (hi < lo)
            throw Error(r.file + ": the voxel region asked for lies outside the image (please report this)");
        region.SetIndex(a, lo);
        region.SetSize(a, static_cast<itk::SizeValueType>(hi - lo + 1));
    }
    return region;
}

// Reads the file's voxels as float: all of them, or with a region asked for
// the region (all frames and components); `streamed` says whether the
// reader read the region alone.
VectorImage4::Pointer readVoxels(const ImageFileRead& r, bool& streamed) {
    auto reader = itk::ImageFileReader<VectorImage4>::New();
    reader->SetImageIO(r.io);
    reader->SetFileName(r.file);
    if (r.options.progress) r.options.progress("read", 0.0);
    const VectorImage4::RegionType region = requestedRegion(r);
    try {
        if (!r.options.region.empty()) {
            reader->UpdateOutputInformation();
            reader->GetOutput()->SetRequestedRegion(region);
        }
        reader->Update();
    } catch (const itk::ExceptionObject& e) {
        throw Error(r.file + ": the voxel data cannot be read (" + describe(e) +
                    "). The file is probably truncated or damaged; copy or export it again.");
    } catch (const std::bad_alloc&) {
        throw Error(r.file + ": out of memory while reading the voxel data; use a machine with "
                    "more memory or crop/downsample the scan first.");
    }
    std::uint64_t ioPixels = 1;
    const itk::ImageIORegion& io = r.io->GetIORegion();
    for (unsigned a = 0; a < io.GetImageDimension(); ++a) ioPixels *= io.GetSize(a);
    streamed = !r.options.region.empty() && ioPixels == region.GetNumberOfPixels();
    if (r.options.progress) r.options.progress("read", 1.0);
    return reader->GetOutput();
}

// Copies the chosen scalar volume and the geometry out of ITK's image, which
// is released on return.
RawVolume extractVolume(ImageFileRead& r, VectorImage4::Pointer image) {
    const auto size = image->GetBufferedRegion().GetSize();
    const auto start = image->GetBufferedRegion().GetIndex();
    RawVolume raw;
    raw.format = formatName(*r.io);
    raw.pixelType = componentName(r.component);
    for (int a = 0; a < 3; ++a) {
        raw.dims[a] = static_cast<std::int64_t>(size[a]);
        raw.start[a] = static_cast<std::int64_t>(start[a]);
        raw.fileDims[a] = r.header.size[a];
    }
    copyGeometry(*image, raw);

    const std::int64_t n = raw.count();
    const int comps = static_cast<int>(image->GetNumberOfComponentsPerPixel());
    const std::int64_t pick = std::max(r.options.volumeIndex, 0);
    r.frame = r.choices > 1 ? pick / comps : 0;
    r.comp = r.choices > 1 ? static_cast<int>(pick % comps) : 0;
    raw.values.resize(static_cast<std::size_t>(n));
    const float* base = image->GetBufferPointer() + r.frame * n * comps + r.comp;
    if (comps == 1) {
        std::copy(base, base + n, raw.values.begin());
    } else {
        for (std::int64_t i = 0; i < n; ++i) raw.values[i] = base[i * comps];
    }
    return raw;
}

// NIfTI intensities: NaN back where the file holds non-finite voxels (ITK's
// NIfTI reader zeroes them). Not for label maps: a float label map padded
// with NaN, as resampling with NaN fill writes, keeps NaN as background 0.
void restoreNonFinite(const ImageFileRead& r, RawVolume& raw) {
    const bool nifti = r.format == CheckedFormat::Nifti || r.format == CheckedFormat::NiftiGz;
    if (nifti && !r.options.labels && r.options.region.empty())
        restoreNiftiNonFinite(r.file, raw.values, r.frame, std::max<std::int64_t>(r.frames, 1), r.comp);
}

// The geometry (TIFF carries no usable one: the caller supplies it), its
// check, and the label conversion when a label map was asked for.
void finish(const ImageFileRead& r, RawVolume& raw) {
    if (raw.format == "TIFF") {
        raw.spacing = r.options.sliceSpacing;
        raw.origin = r.options.sliceOrigin;
        raw.direction = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    }
    checkGeometry(raw, r.file);
    if (r.options.labels) convertToLabels(raw, r.file, isIntegerComponent(r.component));
}

}  // namespace

RawVolume readImageFileItk(const std::filesystem::path& path, const LoadOptions& options) {
    ImageFileRead r(path, options);
    checkBeforeIo(r);
    createIo(r);
    checkBeforeHeader(r);
    readHeader(r);
    checkImageKind(r);
    checkVolumeChoice(r);
    checkDataSize(r);
    bool streamed = false;
    RawVolume raw = extractVolume(r, readVoxels(r, streamed));
    raw.streamed = streamed;
    restoreNonFinite(r, raw);
    finish(r, raw);
    return raw;
}

}  // namespace isohex::imaging::detail

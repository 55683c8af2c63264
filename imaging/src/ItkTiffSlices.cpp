// A folder of 2-D TIFF slices read with ITK into one float volume; the
// geometry comes from the caller (TIFF carries no usable physical one).
#include <itkImageSeriesReader.h>
#include <itkTIFFImageIO.h>

#include "FormatChecks.hpp"
#include "ItkIo.hpp"
#include "RawChecks.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {

RawVolume readTiffSlicesItk(const std::vector<std::filesystem::path>& files,
                            const LoadOptions& options) {
    const std::string folder = files.front().parent_path().string();
    for (const auto& f : files) checkTiffLayout(f.string());
    auto io = itk::TIFFImageIO::New();
    io->SetFileName(files.front().string());
    try {
        io->ReadImageInformation();
    } catch (const itk::ExceptionObject& e) {
        throw Error(files.front().string() + ": the TIFF header cannot be read (" + describe(e) + ").");
    }
    if (io->GetNumberOfComponents() != 1) {
        throw Error(files.front().string() + ": TIFF slices with " +
                    std::to_string(io->GetNumberOfComponents()) +
                    " channels are not supported; save single-channel (greyscale) slices.");
    }
    checkMemoryBudget(folder, sliceStackHeader(*io, files.size()), options.maxMemoryMB);

    auto reader = itk::ImageSeriesReader<FloatImage3>::New();
    reader->SetImageIO(io);
    std::vector<std::string> names;
    for (const auto& f : files) names.push_back(f.string());
    reader->SetFileNames(names);
    try {
        reader->Update();
    } catch (const itk::ExceptionObject& e) {
        throw Error(folder + ": reading the TIFF slices failed (" + describe(e) +
                    "). Check that all slices have the same size and none is damaged.");
    }
    FloatImage3::Pointer image = reader->GetOutput();
    RawVolume raw;
    raw.format = "TIFF";
    raw.pixelType = componentName(io->GetComponentType());
    const auto size = image->GetLargestPossibleRegion().GetSize();
    for (int a = 0; a < 3; ++a) raw.dims[a] = static_cast<std::int64_t>(size[a]);
    raw.values.assign(image->GetBufferPointer(), image->GetBufferPointer() + raw.count());
    raw.spacing = options.sliceSpacing;
    raw.origin = options.sliceOrigin;
    checkGeometry(raw, folder);
    if (options.labels) convertToLabels(raw, folder, isIntegerComponent(io->GetComponentType()));
    return raw;
}

}  // namespace isohex::imaging::detail

#include "ReaderPlugins.hpp"

#include "isohex/core/Plugin.hpp"

namespace isohex::imaging::detail {

const ItkReaders& itkReaders() {
    return plugin::load<ItkReaders>(
        "itk", "reads NIfTI, NRRD, MetaImage, TIFF and DICOM scans and finds Otsu's threshold with ITK");
}

const ExrReader& exrReader() { return plugin::load<ExrReader>("exr", "reads OpenEXR slices"); }

}  // namespace isohex::imaging::detail

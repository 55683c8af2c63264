#pragma once
// Internal, ITK: the image types the ITK readers use, and ITK's names and
// values turned into isohex's (format and pixel names, error text, geometry).
#include <cstddef>
#include <string>

#include <itkImage.h>
#include <itkImageIOBase.h>
#include <itkVectorImage.h>

#include "RawVolume.hpp"

namespace isohex::imaging::detail {

using FloatImage3 = itk::Image<float, 3>;
using VectorImage4 = itk::VectorImage<float, 4>;

// The format's usual name ("NIfTI", "DICOM", ...) for an ITK image IO.
std::string formatName(const itk::ImageIOBase& io);
// The component type as isohex reports it ("uint8", "float32", ...).
std::string componentName(itk::IOComponentEnum c);
// True for the integer component types (what a label map should be stored as).
bool isIntegerComponent(itk::IOComponentEnum c);
// An ITK exception's description without its trailing line ends.
std::string describe(const itk::ExceptionObject& e);

// The header of a stack of `slices` 2-D slices read as one float volume, for
// the memory check before the series reader runs.
RawHeader sliceStackHeader(const itk::ImageIOBase& io, std::size_t slices);

// Copies an ITK image's origin, spacing and direction into `raw`.
template <class ImageT>
void copyGeometry(const ImageT& image, RawVolume& raw) {
    const auto& o = image.GetOrigin();
    const auto& s = image.GetSpacing();
    const auto& d = image.GetDirection();
    for (int a = 0; a < 3; ++a) {
        raw.origin[a] = o[a];
        raw.spacing[a] = s[a];
        for (int b = 0; b < 3; ++b) raw.direction[3 * a + b] = d(a, b);
    }
}

}  // namespace isohex::imaging::detail

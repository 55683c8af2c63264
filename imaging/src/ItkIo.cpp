// ITK's names and values turned into isohex's (see ItkIo.hpp).
#include "ItkIo.hpp"

namespace isohex::imaging::detail {

std::string formatName(const itk::ImageIOBase& io) {
    const std::string n = io.GetNameOfClass();
    if (n == "NiftiImageIO") return "NIfTI";
    if (n == "NrrdImageIO") return "NRRD";
    if (n == "MetaImageIO") return "MetaImage";
    if (n == "TIFFImageIO") return "TIFF";
    if (n == "GDCMImageIO") return "DICOM";
    return n;
}

std::string componentName(itk::IOComponentEnum c) {
    switch (c) {
        case itk::IOComponentEnum::UCHAR: return "uint8";
        case itk::IOComponentEnum::CHAR: return "int8";
        case itk::IOComponentEnum::USHORT: return "uint16";
        case itk::IOComponentEnum::SHORT: return "int16";
        case itk::IOComponentEnum::UINT: return "uint32";
        case itk::IOComponentEnum::INT: return "int32";
        case itk::IOComponentEnum::ULONG: return "uint64";
        case itk::IOComponentEnum::LONG: return "int64";
        case itk::IOComponentEnum::ULONGLONG: return "uint64";
        case itk::IOComponentEnum::LONGLONG: return "int64";
        case itk::IOComponentEnum::FLOAT: return "float32";
        case itk::IOComponentEnum::DOUBLE: return "float64";
        default: return "unknown";
    }
}

bool isIntegerComponent(itk::IOComponentEnum c) {
    return c != itk::IOComponentEnum::FLOAT && c != itk::IOComponentEnum::DOUBLE &&
           c != itk::IOComponentEnum::UNKNOWNCOMPONENTTYPE;
}

// ITK's text on one line: it goes into isohex's one-line error, and teem's and
// MetaIO's descriptions run over several lines.
std::string describe(const itk::ExceptionObject& e) {
    std::string d;
    for (char c : std::string(e.GetDescription())) {
        if (c == '\n' || c == '\r') c = ' ';
        if (c == ' ' && !d.empty() && d.back() == ' ') continue;
        d += c;
    }
    while (!d.empty() && d.back() == ' ') d.pop_back();
    return d;
}

RawHeader sliceStackHeader(const itk::ImageIOBase& io, std::size_t slices) {
    RawHeader header;
    header.size = {static_cast<std::int64_t>(io.GetDimensions(0)), static_cast<std::int64_t>(io.GetDimensions(1)),
                   static_cast<std::int64_t>(slices), 1};
    header.bytesPerComponent = 4;  // read as float (DICOM: after rescaling)
    return header;
}

}  // namespace isohex::imaging::detail

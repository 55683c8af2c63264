// The imaging tests' only ITK translation unit: writes test inputs through ITK
// so the readers are checked against an independent writer.
#include "TestSupport.hpp"

#include <atomic>
#include <complex>
#include <cstdlib>
#include <random>
#include <sstream>
#include <stdexcept>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <gdcmReader.h>
#include <gdcmWriter.h>
#include <itkGDCMImageIO.h>
#include <itkGDCMImageIOFactory.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkImageFileWriter.h>
#include <itkImageSeriesWriter.h>
#include <itkMetaDataObject.h>
#include <itkMetaImageIOFactory.h>
#include <itkNiftiImageIOFactory.h>
#include <itkNrrdImageIOFactory.h>
#include <itkTIFFImageIOFactory.h>
#include <itkVectorImage.h>
#include <unistd.h>

namespace isohex::imaging::test {
namespace {

// This folder is not built with ITK's use-file, so register the IOs by hand.
void registerIo() {
    static const bool once = [] {
        itk::NiftiImageIOFactory::RegisterOneFactory();
        itk::NrrdImageIOFactory::RegisterOneFactory();
        itk::MetaImageIOFactory::RegisterOneFactory();
        itk::GDCMImageIOFactory::RegisterOneFactory();
        itk::TIFFImageIOFactory::RegisterOneFactory();
        return true;
    }();
    (void)once;
}

template <class ImageT>
void setGeometry(ImageT& image, const Geometry& g) {
    typename ImageT::PointType o;
    typename ImageT::SpacingType s;
    typename ImageT::DirectionType d;
    d.SetIdentity();
    for (int a = 0; a < 3; ++a) {
        o[a] = g.origin[a];
        s[a] = g.spacing[a];
        for (int b = 0; b < 3; ++b) d(a, b) = g.direction[3 * a + b];
    }
    image.SetOrigin(o);
    image.SetSpacing(s);
    image.SetDirection(d);
}

template <class T>
typename itk::Image<T, 3>::Pointer makeImage(const Dims& dims, const std::vector<T>& v,
                                             const Geometry& g) {
    using ImageT = itk::Image<T, 3>;
    auto image = ImageT::New();
    typename ImageT::SizeType size;
    for (int a = 0; a < 3; ++a) size[a] = dims[a];
    image->SetRegions(typename ImageT::RegionType(size));
    image->Allocate();
    setGeometry(*image, g);
    if (!v.empty()) std::copy(v.begin(), v.end(), image->GetBufferPointer());
    return image;
}

template <class ImageT>
void write(const ImageT* image, const fs::path& path, bool compress = false) {
    registerIo();
    auto writer = itk::ImageFileWriter<ImageT>::New();
    writer->SetUseCompression(compress);
    writer->SetInput(image);
    writer->SetFileName(path.string());
    writer->Update();
}

std::string uidSuffix() {
    static std::mt19937_64 rng(std::random_device{}());
    return std::to_string(rng() % 1000000000000ULL);
}

std::string joined(double a, double b, double c = std::numeric_limits<double>::quiet_NaN()) {
    std::ostringstream s;
    s.precision(10);
    s << a << "\\" << b;
    if (c == c) s << "\\" << c;
    return s.str();
}

}  // namespace

fs::path sharedData() {
    if (const char* env = std::getenv("ISOHEX_SHARED_DATA")) return env;
    return fs::path(__FILE__).parent_path() / "../../../shared/data";
}

fs::path scratchDir(const std::string& name) {
    static std::atomic<int> counter{0};
    const fs::path dir = fs::temp_directory_path() /
                         ("isohex_imaging_" + std::to_string(getpid()) + "_" +
                          std::to_string(counter++) + "_" + name);
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

void writeImage(const fs::path& path, const Dims& dims, const std::vector<std::int16_t>& v,
                const Geometry& g) {
    write(makeImage<std::int16_t>(dims, v, g).GetPointer(), path);
}
void writeImage(const fs::path& path, const Dims& dims, const std::vector<std::uint8_t>& v,
                const Geometry& g) {
    write(makeImage<std::uint8_t>(dims, v, g).GetPointer(), path);
}
void writeImage(const fs::path& path, const Dims& dims, const std::vector<float>& v,
                const Geometry& g, bool compress) {
    write(makeImage<float>(dims, v, g).GetPointer(), path, compress);
}

void writeDicomSeries(const fs::path& dir, const Dims& dims, const std::vector<std::int16_t>& v,
                      const Geometry& g, const std::string& seriesUid, double slope,
                      double intercept, const std::string& prefix) {
    registerIo();
    fs::create_directories(dir);
    auto image = makeImage<std::int16_t>(dims, v, g);
    using Image2 = itk::Image<std::int16_t, 2>;
    auto io = itk::GDCMImageIO::New();
    io->KeepOriginalUIDOn();  // keep the series UID set below on every slice

    const std::string root = "1.2.826.0.1.3680043.2.1125.99.";
    const std::string study = root + uidSuffix();
    std::vector<itk::MetaDataDictionary> dicts(dims[2]);
    std::vector<itk::MetaDataDictionary*> dictPtrs;
    std::vector<std::string> names;
    for (int z = 0; z < dims[2]; ++z) {
        auto& d = dicts[z];
        const auto p = itkPhysicalPoint(g, {0, 0, z});
        itk::EncapsulateMetaData<std::string>(d, "0008|0060", "CT");
        itk::EncapsulateMetaData<std::string>(d, "0028|0004", "MONOCHROME2");
        itk::EncapsulateMetaData<std::string>(d, "0008|0016", "1.2.840.10008.5.1.4.1.1.2");
        itk::EncapsulateMetaData<std::string>(d, "0008|0018", root + uidSuffix());
        itk::EncapsulateMetaData<std::string>(d, "0020|000d", study);
        itk::EncapsulateMetaData<std::string>(d, "0020|000e", seriesUid);
        itk::EncapsulateMetaData<std::string>(d, "0020|0013", std::to_string(z + 1));
        itk::EncapsulateMetaData<std::string>(d, "0020|0032", joined(p[0], p[1], p[2]));
        const auto& D = g.direction;  // DICOM wants the row (x) and column (y) axes
        std::ostringstream orient;
        orient.precision(10);
        orient << D[0] << "\\" << D[3] << "\\" << D[6] << "\\" << D[1] << "\\" << D[4] << "\\" << D[7];
        itk::EncapsulateMetaData<std::string>(d, "0020|0037", orient.str());
        itk::EncapsulateMetaData<std::string>(d, "0028|0030", joined(g.spacing[1], g.spacing[0]));
        itk::EncapsulateMetaData<std::string>(d, "0018|0050", std::to_string(g.spacing[2]));
        itk::EncapsulateMetaData<std::string>(d, "0028|1053", std::to_string(slope));
        itk::EncapsulateMetaData<std::string>(d, "0028|1052", std::to_string(intercept));
        dictPtrs.push_back(&d);
        names.push_back((dir / (prefix + std::to_string(z) + ".dcm")).string());
    }
    auto writer = itk::ImageSeriesWriter<itk::Image<std::int16_t, 3>, Image2>::New();
    writer->SetInput(image);
    writer->SetImageIO(io);
    writer->SetFileNames(names);
    writer->SetMetaDataDictionaryArray(&dictPtrs);
    writer->Update();
}

void writeMultiFrameDicom(const fs::path& path, const Dims& dims, const std::vector<std::int16_t>& v,
                          const Geometry& g) {
    registerIo();
    auto image = makeImage<std::int16_t>(dims, v, g);
    auto io = itk::GDCMImageIO::New();
    itk::MetaDataDictionary& d = image->GetMetaDataDictionary();  // the writer hands the image's to the IO
    // With modality MR, GDCM stores a 3-D image as one enhanced MR file (frames).
    itk::EncapsulateMetaData<std::string>(d, "0008|0060", "MR");
    itk::EncapsulateMetaData<std::string>(d, "0028|0004", "MONOCHROME2");
    auto writer = itk::ImageFileWriter<itk::Image<std::int16_t, 3>>::New();
    writer->SetInput(image);
    writer->SetImageIO(io);
    writer->SetFileName(path.string());
    writer->Update();
}

std::string dicomTag(const fs::path& file, const std::string& tag) {
    auto io = itk::GDCMImageIO::New();
    io->SetFileName(file.string());
    io->ReadImageInformation();
    std::string value;
    itk::ExposeMetaData<std::string>(io->GetMetaDataDictionary(), tag, value);
    while (!value.empty() && value.back() == ' ') value.pop_back();
    return value;
}

void writeComplexImage(const fs::path& path, const Dims& dims) {
    using ImageT = itk::Image<std::complex<float>, 3>;
    auto image = ImageT::New();
    ImageT::SizeType size;
    for (int a = 0; a < 3; ++a) size[a] = dims[a];
    image->SetRegions(ImageT::RegionType(size));
    image->Allocate();
    image->FillBuffer(std::complex<float>(1.0f, 2.0f));
    write(image.GetPointer(), path);
}

void write4DImage(const fs::path& path, const Dims& dims, int frames) {
    using ImageT = itk::Image<float, 4>;
    auto image = ImageT::New();
    ImageT::SizeType size;
    for (int a = 0; a < 3; ++a) size[a] = dims[a];
    size[3] = frames;
    image->SetRegions(ImageT::RegionType(size));
    image->Allocate();
    const std::size_t n = std::size_t(dims[0]) * dims[1] * dims[2];
    for (int f = 0; f < frames; ++f)
        std::fill(image->GetBufferPointer() + f * n, image->GetBufferPointer() + (f + 1) * n, float(f));
    write(image.GetPointer(), path);
}

void writeVectorImage(const fs::path& path, const Dims& dims, int components) {
    using ImageT = itk::VectorImage<float, 3>;
    auto image = ImageT::New();
    ImageT::SizeType size;
    for (int a = 0; a < 3; ++a) size[a] = dims[a];
    image->SetRegions(ImageT::RegionType(size));
    image->SetNumberOfComponentsPerPixel(components);
    image->Allocate();
    const std::size_t n = std::size_t(dims[0]) * dims[1] * dims[2];
    float* p = image->GetBufferPointer();
    for (std::size_t i = 0; i < n; ++i)
        for (int c = 0; c < components; ++c) p[i * components + c] = float(c);
    write(image.GetPointer(), path);
}

void writeExrSlice(const fs::path& path, int width, int height, const std::vector<float>& v) {
    Imf::Header header(width, height);
    header.channels().insert("Y", Imf::Channel(Imf::FLOAT));
    Imf::OutputFile out(path.string().c_str(), header);
    Imf::FrameBuffer fb;
    fb.insert("Y", Imf::Slice(Imf::FLOAT, (char*)v.data(), sizeof(float), sizeof(float) * width));
    out.setFrameBuffer(fb);
    out.writePixels(height);
}

std::array<double, 3> itkPhysicalPoint(const fs::path& path, const std::array<long, 3>& index) {
    registerIo();
    using ImageT = itk::Image<float, 3>;
    auto reader = itk::ImageFileReader<ImageT>::New();
    reader->SetFileName(path.string());
    reader->UpdateOutputInformation();
    ImageT::IndexType i;
    for (int a = 0; a < 3; ++a) i[a] = index[a];
    ImageT::PointType p;
    reader->GetOutput()->TransformIndexToPhysicalPoint(i, p);
    return {p[0], p[1], p[2]};
}

std::array<double, 3> itkPhysicalPoint(const Geometry& g, const std::array<long, 3>& index) {
    auto image = itk::Image<float, 3>::New();
    setGeometry(*image, g);
    itk::Image<float, 3>::IndexType i;
    for (int a = 0; a < 3; ++a) i[a] = index[a];
    itk::Image<float, 3>::PointType p;
    image->TransformIndexToPhysicalPoint(i, p);
    return {p[0], p[1], p[2]};
}

void setDicomElement(const fs::path& file, std::uint16_t group, std::uint16_t element, const std::string& bytes) {
    gdcm::Reader reader;
    reader.SetFileName(file.c_str());
    if (!reader.Read()) throw std::runtime_error("GDCM cannot read " + file.string());
    gdcm::DataSet& ds = reader.GetFile().GetDataSet();
    const gdcm::Tag tag(group, element);
    gdcm::DataElement de = ds.FindDataElement(tag) ? ds.GetDataElement(tag) : gdcm::DataElement(tag);
    de.SetByteValue(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
    ds.Replace(de);
    gdcm::Writer writer;
    writer.SetFile(reader.GetFile());
    writer.SetFileName(file.c_str());
    if (!writer.Write()) throw std::runtime_error("GDCM cannot write " + file.string());
}

}  // namespace isohex::imaging::test

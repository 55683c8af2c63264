#pragma once
// Helpers for the imaging tests: scratch folders, the shared real data, and
// writers that produce test inputs through ITK and OpenEXR (independent of the
// readers under test). ITK itself stays inside TestSupport.cpp.
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace isohex::imaging::test {

namespace fs = std::filesystem;

// Runs `f`, expects isohex::Error (a GoogleTest failure otherwise), checks
// that its message mentions every piece, and returns the message.
std::string expectError(const std::function<void()>& f, const std::vector<std::string>& pieces);
// A file's bytes, written and read whole.
void writeBytes(const fs::path& p, const std::string& bytes);
std::string readAll(const fs::path& p);

// The folder of real scans (env ISOHEX_SHARED_DATA, set by ctest).
fs::path sharedData();
// A fresh empty folder under the system temp dir, unique per test.
fs::path scratchDir(const std::string& name);

struct Geometry {
    std::array<double, 3> origin{0, 0, 0};
    std::array<double, 3> spacing{1, 1, 1};
    std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};  // row-major, columns = axes
};

using Dims = std::array<int, 3>;

// Scalar 3-D images; the format follows the extension (.nii, .nii.gz, .nrrd,
// .nhdr, .mha, .mhd, .tif). `compress` asks the writer to compress the voxels.
void writeImage(const fs::path& path, const Dims& dims, const std::vector<std::int16_t>& v,
                const Geometry& g);
void writeImage(const fs::path& path, const Dims& dims, const std::vector<std::uint8_t>& v,
                const Geometry& g);
void writeImage(const fs::path& path, const Dims& dims, const std::vector<float>& v,
                const Geometry& g, bool compress = false);
// One DICOM file per slice through ImageSeriesWriter + GDCMImageIO.
void writeDicomSeries(const fs::path& dir, const Dims& dims, const std::vector<std::int16_t>& v,
                      const Geometry& g, const std::string& seriesUid, double rescaleSlope = 1.0,
                      double rescaleIntercept = 0.0, const std::string& prefix = "slice");
// A tag of a DICOM file as text ("" when absent), e.g. "0028|1053".
// One multi-frame DICOM file holding the whole volume (ImageFileWriter + GDCMImageIO).
void writeMultiFrameDicom(const fs::path& path, const Dims& dims, const std::vector<std::int16_t>& v,
                          const Geometry& g);
std::string dicomTag(const fs::path& file, const std::string& tag);
// Sets a data element of a DICOM file to `bytes` (its value as stored: text,
// or little-endian binary), through GDCM's reader and writer.
void setDicomElement(const fs::path& file, std::uint16_t group, std::uint16_t element, const std::string& bytes);
// Images the loader must refuse or handle specially.
void writeComplexImage(const fs::path& path, const Dims& dims);
void write4DImage(const fs::path& path, const Dims& dims, int frames);  // value = frame index
void writeVectorImage(const fs::path& path, const Dims& dims, int components);  // value = component
// A 2-D single-channel float EXR slice.
void writeExrSlice(const fs::path& path, int width, int height, const std::vector<float>& v);

// ITK's TransformIndexToPhysicalPoint for the image stored in `path` (read back by ITK).
std::array<double, 3> itkPhysicalPoint(const fs::path& path, const std::array<long, 3>& index);
// The same for an in-memory image with this geometry.
std::array<double, 3> itkPhysicalPoint(const Geometry& g, const std::array<long, 3>& index);

}  // namespace isohex::imaging::test

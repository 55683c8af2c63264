// VTK XML unstructured grid (.vtu) through the VTK library.
//
// Written as raw binary appended data with Float64 points and 64-bit block
// headers. Cell data: material (Int32), scaled_jacobian (Float64) and any
// WriteOptions::cellFields (Float64). Point data:
// node_class (Int32, NodeKind), node_surface (Int32, NodeClass::id) and any
// WriteOptions::pointFields (Float64); WriteOptions::fieldData as field data. Field
// data surface_inside / surface_outside / surface_names keep HexMesh::surfaces,
// so a .vtu written by isohex reads back into the same HexMesh.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <mutex>
#include <new>
#include <string>

#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkCellTypes.h>
#include <vtkDoubleArray.h>
#include <vtkErrorCode.h>
#include <vtkFieldData.h>
#include <vtkIdTypeArray.h>
#include <vtkIntArray.h>
#include <vtkLogger.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkOutputWindow.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkUnsignedCharArray.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include "MeshIODetail.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::io::detail {

namespace {

// Collects what VTK would print, so a failure becomes one Error line and the
// user's terminal never sees VTK's multi-line reports.
class CapturingOutputWindow : public vtkOutputWindow {
public:
    static CapturingOutputWindow* New();
    vtkTypeMacro(CapturingOutputWindow, vtkOutputWindow);

    void DisplayText(const char* t) override { keep(t, false); }
    void DisplayErrorText(const char* t) override { keep(t, true); }
    void DisplayWarningText(const char* t) override { keep(t, false); }
    void DisplayGenericWarningText(const char* t) override { keep(t, false); }
    void DisplayDebugText(const char*) override {}

    std::string firstError;
    std::string firstWarning;

private:
    void keep(const char* t, bool error) {
        std::string& slot = error ? firstError : firstWarning;
        if (slot.empty() && t) slot = oneLine(t);
    }

    // VTK reports look like "ERROR: In /path/file.cxx, line 12\nvtkClass (0x...): what\n\n".
    // Keep "what", on one line.
    static std::string oneLine(const std::string& text) {
        std::string s = text;
        const auto nl = s.find('\n');
        if (s.rfind("ERROR: In ", 0) == 0 || s.rfind("Warning: In ", 0) == 0 ||
            s.rfind("Generic Warning: In ", 0) == 0)
            s = nl == std::string::npos ? "" : s.substr(nl + 1);
        const auto cut = s.find("): ");
        if (cut != std::string::npos && cut < 80) s = s.substr(cut + 3);
        std::string out;
        for (char c : s) {
            if (c == '\n' || c == '\r' || c == '\t') c = ' ';
            if (c == ' ' && (out.empty() || out.back() == ' ')) continue;
            out.push_back(c);
        }
        while (!out.empty() && (out.back() == ' ' || out.back() == '.')) out.pop_back();
        return out;
    }
};
vtkStandardNewMacro(CapturingOutputWindow);

// Installs a CapturingOutputWindow for its lifetime and mutes VTK's logger on
// stderr, which VTK 9 writes to besides the output window. Both are
// process-wide, so VTK file work in this module is serialised.
class VtkMessageCapture {
public:
    VtkMessageCapture() : lock_(mutex()) {
        previous_ = vtkOutputWindow::GetInstance();
        vtkOutputWindow::SetInstance(window_);
        stderrVerbosity_ = vtkLogger::GetCurrentVerbosityCutoff();
        vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
    }
    ~VtkMessageCapture() {
        vtkLogger::SetStderrVerbosity(stderrVerbosity_);
        vtkOutputWindow::SetInstance(previous_);
    }
    VtkMessageCapture(const VtkMessageCapture&) = delete;
    VtkMessageCapture& operator=(const VtkMessageCapture&) = delete;

    const std::string& error() const { return window_->firstError; }
    const std::string& warning() const { return window_->firstWarning; }

private:
    static std::mutex& mutex() {
        static std::mutex m;
        return m;
    }
    std::lock_guard<std::mutex> lock_;
    vtkSmartPointer<vtkOutputWindow> previous_;
    vtkNew<CapturingOutputWindow> window_;
    vtkLogger::Verbosity stderrVerbosity_ = vtkLogger::VERBOSITY_INFO;
};

// Sizes `a` to n tuples; VTK reports a failed allocation and leaves the
// array empty, so that becomes std::bad_alloc (the run's out-of-memory error).
void requireTuples(vtkDataArray* a, vtkIdType n) {
    a->SetNumberOfTuples(n);
    if (a->GetNumberOfTuples() != n) throw std::bad_alloc();
}

vtkSmartPointer<vtkIntArray> intArray(const char* name, vtkIdType n) {
    auto a = vtkSmartPointer<vtkIntArray>::New();
    a->SetName(name);
    requireTuples(a, n);
    return a;
}

vtkSmartPointer<vtkDoubleArray> doubleArray(const std::string& name, const std::vector<double>& values) {
    auto a = vtkSmartPointer<vtkDoubleArray>::New();
    a->SetName(name.c_str());
    requireTuples(a, static_cast<vtkIdType>(values.size()));
    for (std::size_t i = 0; i < values.size(); ++i) a->SetValue(static_cast<vtkIdType>(i), values[i]);
    return a;
}

// The single-component arrays of `data` named in `names` that it has, as doubles.
std::vector<std::pair<std::string, std::vector<double>>> namedArrays(vtkFieldData* data,
                                                                     const std::vector<std::string>& names) {
    std::vector<std::pair<std::string, std::vector<double>>> out;
    for (const auto& name : names) {
        vtkDataArray* a = data ? data->GetArray(name.c_str()) : nullptr;
        if (!a || a->GetNumberOfComponents() != 1) continue;
        std::vector<double> v(static_cast<std::size_t>(a->GetNumberOfTuples()));
        for (vtkIdType i = 0; i < a->GetNumberOfTuples(); ++i) v[static_cast<std::size_t>(i)] = a->GetComponent(i, 0);
        out.emplace_back(name, std::move(v));
    }
    return out;
}

// An integer-valued array of `data`, or null when there is none. Any numeric
// type is accepted; non-integral values are an error, not a silent rounding.
vtkDataArray* integerArray(vtkFieldData* data, const char* name, vtkIdType expected, const std::string& path,
                           const char* where) {
    vtkDataArray* a = data->GetArray(name);
    if (!a) return nullptr;
    if (a->GetNumberOfComponents() != 1 || a->GetNumberOfTuples() != expected)
        throw Error(path + ": " + where + " array '" + name + "' has " + std::to_string(a->GetNumberOfTuples()) +
                    " values of " + std::to_string(a->GetNumberOfComponents()) + " components; expected " +
                    std::to_string(expected) + " single values");
    return a;
}

std::int32_t integerValue(vtkDataArray* a, vtkIdType i, const std::string& path, const char* name) {
    const double v = a->GetComponent(i, 0);
    if (!std::isfinite(v) || v != std::floor(v) || v < -2147483648.0 || v > 2147483647.0)
        throw Error(path + ": array '" + name + "' value " + std::to_string(i) + " is " + std::to_string(v) +
                    ", not a 32-bit integer");
    return static_cast<std::int32_t>(v);
}

// A complete VTK XML file ends with </VTKFile>. Checking that first turns the
// common damage (an interrupted copy or write) into a precise message, and
// keeps VTK from parsing a cut-off appended block, where VTK 9.1 sizes arrays
// from values it never read.
void requireCompleteXml(const std::string& path) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    const std::streamoff size = in ? static_cast<std::streamoff>(in.tellg()) : 0;
    const std::streamoff tail = std::min<std::streamoff>(size, 256);
    std::string end(static_cast<std::size_t>(tail), '\0');
    in.seekg(size - tail);
    in.read(end.data(), tail);
    while (!end.empty() && std::isspace(static_cast<unsigned char>(end.back()))) end.pop_back();
    const std::string closing = "</VTKFile>";
    if (end.size() < closing.size() || end.compare(end.size() - closing.size(), closing.size(), closing) != 0)
        throw Error(path + ": truncated or not a VTK XML file (it does not end with " + closing + ")");
}

// The value of attribute `name` in the first element `tag` of `xml`, or "".
std::string attributeOf(const std::string& xml, const std::string& tag, const std::string& name) {
    const std::size_t at = xml.find("<" + tag);
    if (at == std::string::npos) return {};
    const std::size_t end = xml.find('>', at);
    const std::string element = xml.substr(at, end == std::string::npos ? std::string::npos : end - at);
    const std::size_t a = element.find(" " + name + "=");
    if (a == std::string::npos) return {};
    const std::size_t open = a + name.size() + 2;
    if (open >= element.size()) return {};
    const char quote = element[open];
    const std::size_t close = element.find(quote, open + 1);
    return close == std::string::npos ? std::string() : element.substr(open + 1, close - open - 1);
}

// VTK sizes its arrays from a piece's NumberOfPoints and NumberOfCells
// before it reads a value, so a header claiming 2e9 cells allocated gigabytes
// and then failed as "out of memory". Each point takes at least 6 bytes of
// the file (three ASCII digits with their blanks) and each hexahedron at least
// 10 (eight connectivity entries, an offset and a type); compressed data
// (VTK's blocks, at most 32 KiB each with a 4-byte size apiece) at least
// 1/8192 of that. A header whose counts need more than the file has is
// refused before VTK reads it.
void requireCountsFitTheFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::string head(65536, '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    head.resize(static_cast<std::size_t>(in.gcount()));
    const std::size_t appended = head.find("<AppendedData");
    if (appended != std::string::npos) head.resize(appended);
    auto count = [&](const char* name) -> double {
        const std::string v = attributeOf(head, "Piece", name);
        if (v.empty()) return 0.0;  // no piece: VTK's own error
        char* end = nullptr;
        const double x = std::strtod(v.c_str(), &end);
        // VTK took a negative count as a size and crashed
        if (end == v.c_str() || !(x >= 0) || x != std::floor(x))
            throw Error(path + ": the header's " + name + " is '" + boundedMessage(v, 40) +
                        "', not a count; the file is damaged. Write or export the mesh again.");
        return x;
    };
    const double points = count("NumberOfPoints"), cells = count("NumberOfCells");
    const bool compressed = !attributeOf(head, "VTKFile", "compressor").empty();
    const double need = (6.0 * points + 10.0 * cells) / (compressed ? 8192.0 : 1.0);
    std::error_code ec;
    const auto size = std::filesystem::file_size(path, ec);
    if (ec || need <= static_cast<double>(size)) return;
    std::ostringstream m;
    m.precision(15);
    m << path << ": the header declares " << points << " points and " << cells << " cells, which need at least "
      << static_cast<long long>(need) << " bytes" << (compressed ? " even compressed" : "") << ", but the file has "
      << size << "; the header is damaged or the file truncated. Write or export the mesh again.";
    throw Error(m.str());
}

}  // namespace

void writeVtu(const HexMesh& mesh, const std::string& tmpPath, const std::string& path,
              const std::vector<double>& scaledJacobian, const WriteOptions& opt) {
    const auto nNodes = static_cast<vtkIdType>(mesh.nodeCount());
    const auto nHexes = static_cast<vtkIdType>(mesh.hexCount());
    // From the first array on: an allocation VTK cannot make is reported by
    // VTK on stderr and leaves the array empty.
    VtkMessageCapture capture;

    vtkNew<vtkUnstructuredGrid> grid;

    vtkNew<vtkDoubleArray> coords;
    coords->SetNumberOfComponents(3);
    requireTuples(coords, nNodes);
    double* c = coords->GetPointer(0);
    for (vtkIdType i = 0; i < nNodes; ++i)
        for (int k = 0; k < 3; ++k) c[3 * i + k] = mesh.nodes[i][k];
    vtkNew<vtkPoints> points;
    points->SetData(coords);
    grid->SetPoints(points);

    vtkNew<vtkIdTypeArray> offsets, connectivity;
    requireTuples(offsets, nHexes + 1);
    requireTuples(connectivity, 8 * nHexes);
    vtkIdType* off = offsets->GetPointer(0);
    vtkIdType* conn = connectivity->GetPointer(0);
    for (vtkIdType h = 0; h <= nHexes; ++h) off[h] = 8 * h;
    for (vtkIdType h = 0; h < nHexes; ++h)
        for (int k = 0; k < 8; ++k) conn[8 * h + k] = mesh.hexes[h][k];
    vtkNew<vtkCellArray> cells;
    cells->SetData(offsets, connectivity);
    grid->SetCells(VTK_HEXAHEDRON, cells);

    auto material = intArray("material", nHexes);
    for (vtkIdType h = 0; h < nHexes; ++h) material->SetValue(h, mesh.material[h]);
    grid->GetCellData()->AddArray(material);
    vtkNew<vtkDoubleArray> sj;
    sj->SetName("scaled_jacobian");
    requireTuples(sj, nHexes);
    for (vtkIdType h = 0; h < nHexes; ++h) sj->SetValue(h, scaledJacobian[h]);
    grid->GetCellData()->AddArray(sj);
    for (const auto& [name, values] : opt.cellFields) grid->GetCellData()->AddArray(doubleArray(name, values));
    for (const auto& [name, values] : opt.pointFields) grid->GetPointData()->AddArray(doubleArray(name, values));
    for (const auto& [name, values] : opt.fieldData) grid->GetFieldData()->AddArray(doubleArray(name, values));

    auto kind = intArray("node_class", nNodes);
    auto surface = intArray("node_surface", nNodes);
    for (vtkIdType i = 0; i < nNodes; ++i) {
        kind->SetValue(i, static_cast<int>(mesh.nodeClass[i].kind));
        surface->SetValue(i, mesh.nodeClass[i].id);
    }
    grid->GetPointData()->AddArray(kind);
    grid->GetPointData()->AddArray(surface);

    if (!mesh.surfaces.empty()) {
        const auto nSurf = static_cast<vtkIdType>(mesh.surfaces.size());
        auto inside = intArray("surface_inside", nSurf);
        auto outside = intArray("surface_outside", nSurf);
        // Names as one byte array, each name ended by '\n': a VTK string array
        // would be an <Array> element, which meshio's raw-binary reader rejects.
        vtkNew<vtkUnsignedCharArray> names;
        names->SetName("surface_names");
        for (vtkIdType s = 0; s < nSurf; ++s) {
            inside->SetValue(s, mesh.surfaces[s].inside);
            outside->SetValue(s, mesh.surfaces[s].outside);
            for (char ch : mesh.surfaces[s].name) names->InsertNextValue(static_cast<unsigned char>(ch == '\n' ? ' ' : ch));
            names->InsertNextValue('\n');
        }
        grid->GetFieldData()->AddArray(inside);
        grid->GetFieldData()->AddArray(outside);
        grid->GetFieldData()->AddArray(names);
    }

    vtkNew<vtkXMLUnstructuredGridWriter> writer;
    writer->SetFileName(tmpPath.c_str());
    writer->SetInputData(grid);
    writer->SetDataModeToAppended();
    writer->EncodeAppendedDataOff();
    writer->SetCompressorTypeToNone();
    writer->SetHeaderTypeToUInt64();
    const int ok = writer->Write();
    if (!ok || writer->GetErrorCode() != vtkErrorCode::NoError || !capture.error().empty()) {
        // The error code names the cause (out of disk space, cannot open);
        // the captured text only says that the pipeline request failed.
        std::string why;
        if (writer->GetErrorCode() != vtkErrorCode::NoError)
            why = vtkErrorCode::GetStringFromErrorCode(writer->GetErrorCode());
        if (why.empty()) why = capture.error();
        if (why.empty()) why = "unknown VTK error";
        throw Error(path + ": could not write the VTU file: " + why);
    }
}

HexMesh readVtu(const std::string& path, const ArrayRequest* arrays) {
    requireCompleteXml(path);
    requireCountsFitTheFile(path);
    VtkMessageCapture capture;
    vtkNew<vtkXMLUnstructuredGridReader> reader;
    if (!reader->CanReadFile(path.c_str()))
        throw Error(path + ": not a VTK XML unstructured grid (.vtu) file" +
                    (capture.error().empty() ? std::string() : " (" + capture.error() + ")"));
    reader->SetFileName(path.c_str());
    reader->Update();
    if (reader->GetErrorCode() != vtkErrorCode::NoError || !capture.error().empty()) {
        std::string why = capture.error();
        if (why.empty()) why = vtkErrorCode::GetStringFromErrorCode(reader->GetErrorCode());
        throw Error(path + ": damaged or truncated .vtu file: " + why);
    }
    vtkUnstructuredGrid* grid = reader->GetOutput();
    if (!grid || grid->GetNumberOfPoints() == 0)
        throw Error(path + ": the .vtu file holds no points (empty, damaged or truncated)");
    if (grid->GetNumberOfPieces() > 1 || reader->GetNumberOfPieces() > 1)
        throw Error(path + ": .vtu files with several pieces are not supported");

    const vtkIdType nNodes = grid->GetNumberOfPoints();
    const vtkIdType nCells = grid->GetNumberOfCells();
    if (nNodes > 2147483647 || nCells > 2147483647)
        throw Error(path + ": too many points or cells for 32-bit indices");

    HexMesh mesh;
    mesh.nodes.resize(nNodes);
    mesh.nodeClass.resize(nNodes);
    for (vtkIdType i = 0; i < nNodes; ++i) {
        double p[3];
        grid->GetPoint(i, p);
        mesh.nodes[i] = {p[0], p[1], p[2]};
    }

    vtkCellArray* cells = grid->GetCells();
    if (!cells || cells->GetNumberOfCells() != nCells)
        throw Error(path + ": the .vtu file's cell list is damaged");
    mesh.hexes.resize(nCells);
    mesh.material.assign(nCells, 1);
    vtkNew<vtkIdList> ids;
    for (vtkIdType c = 0; c < nCells; ++c) {
        const int type = grid->GetCellType(c);
        if (type != VTK_HEXAHEDRON) {
            const char* name = vtkCellTypes::GetClassNameFromTypeId(type);
            throw Error(path + ": cell " + std::to_string(c) + " is a " + (name ? name : "unknown cell") +
                        " (VTK type " + std::to_string(type) +
                        "); isohex reads only hexahedra (VTK type 12, 8 nodes)");
        }
        cells->GetCellAtId(c, ids);
        if (ids->GetNumberOfIds() != 8)
            throw Error(path + ": hexahedron " + std::to_string(c) + " has " + std::to_string(ids->GetNumberOfIds()) +
                        " nodes instead of 8");
        for (int k = 0; k < 8; ++k) {
            const vtkIdType v = ids->GetId(k);
            if (v < 0 || v >= nNodes)
                throw Error(path + ": hexahedron " + std::to_string(c) + " refers to point " + std::to_string(v) +
                            " but the file has " + std::to_string(nNodes) + " points");
            mesh.hexes[c][k] = static_cast<Index>(v);
        }
    }

    if (vtkDataArray* a = integerArray(grid->GetCellData(), "material", nCells, path, "cell"))
        for (vtkIdType c = 0; c < nCells; ++c) mesh.material[c] = integerValue(a, c, path, "material");

    vtkDataArray* kind = integerArray(grid->GetPointData(), "node_class", nNodes, path, "point");
    vtkDataArray* surf = integerArray(grid->GetPointData(), "node_surface", nNodes, path, "point");
    for (vtkIdType i = 0; kind && i < nNodes; ++i) {
        const std::int32_t k = integerValue(kind, i, path, "node_class");
        if (k < 0 || k > 3)
            throw Error(path + ": point " + std::to_string(i) + " has node_class " + std::to_string(k) +
                        "; expected 0 (interior), 1 (surface), 2 (curve) or 3 (fixed)");
        mesh.nodeClass[i].kind = static_cast<NodeKind>(k);
    }
    for (vtkIdType i = 0; surf && i < nNodes; ++i) mesh.nodeClass[i].id = integerValue(surf, i, path, "node_surface");

    vtkFieldData* fd = grid->GetFieldData();
    vtkDataArray* in = fd ? fd->GetArray("surface_inside") : nullptr;
    vtkDataArray* out = fd ? fd->GetArray("surface_outside") : nullptr;
    vtkDataArray* names = fd ? fd->GetArray("surface_names") : nullptr;
    if (in && out && in->GetNumberOfTuples() == out->GetNumberOfTuples()) {
        std::vector<std::string> nameList;
        if (names && names->GetNumberOfComponents() == 1) {
            std::string current;
            for (vtkIdType i = 0; i < names->GetNumberOfTuples(); ++i) {
                const auto ch = static_cast<char>(static_cast<int>(names->GetComponent(i, 0)));
                if (ch == '\n') nameList.push_back(std::move(current)), current.clear();
                else current.push_back(ch);
            }
        }
        const vtkIdType n = in->GetNumberOfTuples();
        for (vtkIdType s = 0; s < n; ++s) {
            SurfaceTag t;
            t.inside = integerValue(in, s, path, "surface_inside");
            t.outside = integerValue(out, s, path, "surface_outside");
            if (static_cast<std::size_t>(s) < nameList.size()) t.name = nameList[s];
            mesh.surfaces.push_back(std::move(t));
        }
    }
    if (arrays) {
        arrays->out.pointFields = namedArrays(grid->GetPointData(), arrays->pointNames);
        arrays->out.fieldData = namedArrays(fd, arrays->fieldNames);
    }
    return mesh;
}

}  // namespace isohex::io::detail

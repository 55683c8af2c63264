#pragma once
// Private to the mesh-file writers and readers (core/src/MeshIO*.cpp).
//
// Each writer is called by io::write with the temporary path it must fill and
// the user's path, which is the one every error message names.
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "isohex/core/HexMesh.hpp"
#include "isohex/core/MeshIO.hpp"
#include "isohex/core/Topology.hpp"

namespace isohex::io::detail {

// Writes opt's cellFields, pointFields and fieldData as Float64 arrays.
void writeVtu(const HexMesh& mesh, const std::string& tmpPath, const std::string& path,
              const std::vector<double>& scaledJacobian, const WriteOptions& opt);
void writeMsh(const HexMesh& mesh, const std::string& tmpPath, const std::string& path);
void writeExodus(const HexMesh& mesh, const std::string& tmpPath, const std::string& path);
void writeAbaqus(const HexMesh& mesh, const std::string& tmpPath, const std::string& path);
void writeMedit(const HexMesh& mesh, const std::string& tmpPath, const std::string& path);

// The arrays readWithArrays asks for, and where they go.
struct ArrayRequest {
    const std::vector<std::string>& pointNames;
    const std::vector<std::string>& fieldNames;
    NamedArrays& out;
};
HexMesh readVtu(const std::string& path, const ArrayRequest* arrays = nullptr);
HexMesh readMsh(const std::string& path);

// Throws an Error naming `path` unless it is an existing, readable regular file.
void requireReadableFile(const std::string& path);

// The distinct material ids of the mesh, ascending.
std::vector<std::int32_t> materialsOf(const HexMesh& mesh);
// Ids for formats that need positive ones (Gmsh physical tags, Exodus block
// ids): each material > 0 keeps its value, the others take the smallest
// positive values no material uses. `mats` must be ascending (materialsOf).
std::vector<int> positiveIds(const std::vector<std::int32_t>& mats);
// The hexes of each material of `mats` (materialsOf(mesh)), ascending; one pass.
std::vector<std::vector<Index>> hexesByMaterial(const HexMesh& mesh, const std::vector<std::int32_t>& mats);

// The boundary and interface surfaces of the mesh with the name each gets in
// files: SurfacePatch::tag.name if set, else the name of the matching entry of
// HexMesh::surfaces, else surfaceName(tag).
struct NamedPatch {
    std::string name;
    SurfacePatch patch;
};
std::vector<NamedPatch> namedSurfaces(const HexMesh& mesh);

// The four corners of local face `face` of `hex`, ordered so that the
// right-hand normal points out of that hex.
std::array<Index, 4> faceNodes(const HexMesh& mesh, Index hex, int face);

// Buffered text output that turns every I/O failure into an Error naming the
// user's file. close() must be called; the destructor only releases.
class TextOut {
public:
    TextOut(const std::string& tmpPath, const std::string& path);
    ~TextOut();
    TextOut(const TextOut&) = delete;
    TextOut& operator=(const TextOut&) = delete;

    TextOut& operator<<(std::string_view s);
    TextOut& operator<<(char c);
    TextOut& operator<<(std::int64_t v);
    TextOut& operator<<(std::int32_t v) { return *this << static_cast<std::int64_t>(v); }
    TextOut& operator<<(std::size_t v) { return *this << static_cast<std::int64_t>(v); }
    // Shortest decimal text that reads back to the identical double.
    TextOut& operator<<(double v);
    void close();

private:
    void flush();
    std::FILE* file_ = nullptr;
    std::string path_;
    std::string buffer_;
};

}  // namespace isohex::io::detail

#pragma once
// Mesh files. The format follows the file extension:
//   .vtu            VTK XML unstructured grid (VTK library), read and write
//   .msh            Gmsh MSH 4.1 (Gmsh library), read and write
//   .exo .e .ex2    Exodus II (libexodusII), write
//   .inp            Abaqus input (C3D8), write
//   .mesh           MEDIT, write
// Every write goes to a temporary file in the target folder and is renamed
// into place, so a failure never leaves a truncated file or clobbers an old one.
#include <string>
#include <utility>
#include <vector>

#include "isohex/core/HexMesh.hpp"

namespace isohex::io {

enum class Format { Vtu, Msh, Exodus, Abaqus, Medit };

// Throws isohex::Error naming the file and the supported extensions.
Format formatFromPath(const std::string& path);
bool canRead(Format f);
std::vector<std::string> writableExtensions();
std::vector<std::string> readableExtensions();

struct WriteOptions {
    bool overwrite = false;                 // refuse to replace an existing file unless set
    // Optional per-hex scalar written next to the material (VTU cell data
    // "scaled_jacobian"); computed by the writer when empty.
    std::vector<double> scaledJacobian;
    // Further per-hex fields (name, one value per hex), written as cell data
    // where the format has a place for them (.vtu).
    std::vector<std::pair<std::string, std::vector<double>>> cellFields;
    // Per-node fields (name, one value per node) and whole-file arrays (name,
    // any number of values), written as point data and field data where the
    // format has a place for them (.vtu). Whole numbers up to 2^53 keep their
    // value exactly (Float64).
    std::vector<std::pair<std::string, std::vector<double>>> pointFields;
    std::vector<std::pair<std::string, std::vector<double>>> fieldData;
};

// Named arrays read back from a .vtu besides the mesh (see readWithArrays).
struct NamedArrays {
    std::vector<std::pair<std::string, std::vector<double>>> pointFields, fieldData;
    // The values of `name`, or null when the file has no such array.
    const std::vector<double>* point(const std::string& name) const;
    const std::vector<double>* field(const std::string& name) const;
};

// Checks the mesh (HexMesh::checkConsistent; a mesh without hexes is refused),
// then writes it in the format of the extension. Every surface of surfacePatches() becomes a named group:
// a side set + node set (Exodus), an element-based *SURFACE (Abaqus), a
// physical surface of quads (MSH), referenced quadrilaterals (MEDIT).
void write(const HexMesh& mesh, const std::string& path, const WriteOptions& opt = {});

// Reads .vtu (hexahedra only; material from cell array "material", else 1;
// node classes and surfaces when isohex wrote them) or .msh (8-node hexahedra
// of every volume; material from the volume's physical group "material_<id>",
// else the group's tag, else the volume's tag). Node and hex order follow the
// file (MSH: by tag). Throws isohex::Error with one line naming the file for
// missing, damaged, truncated or non-hexahedral files.
HexMesh read(const std::string& path);

// Loads now the plugin (isohex/core/Plugin.hpp) of the format of `path`, if
// it has one (.vtu, .msh, Exodus), as `isohex batch` does before forking its
// jobs. Returns false if it cannot be loaded or the extension is unknown; the
// reason is left to read and write, which throw it for the file concerned.
bool preloadFormat(const std::string& path);
// read() of a .vtu that also returns the point-data and field-data arrays
// named in `pointNames` and `fieldNames` that the file has (as Float64).
HexMesh readWithArrays(const std::string& path, const std::vector<std::string>& pointNames,
                       const std::vector<std::string>& fieldNames, NamedArrays& arrays);

}  // namespace isohex::io

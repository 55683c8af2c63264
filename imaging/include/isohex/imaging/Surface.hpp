#pragma once
// Closed triangle surfaces (.stl ascii/binary, .obj, .ply, .off) as input:
// read through Assimp, checked, and turned into a narrow-band signed distance
// level set (negative inside) with openvdb::tools::meshToLevelSet.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <openvdb/openvdb.h>

#include "isohex/core/HexMesh.hpp"  // Vec3
#include "isohex/imaging/ImplicitField.hpp"

namespace isohex::imaging {

struct TriangleSurface {
    std::vector<Vec3> vertices;                        // world units of the file
    std::vector<std::array<std::int32_t, 3>> triangles;  // outward (counter-clockwise seen from outside)
    std::string source;
    bool flipped = false;              // the file was oriented inwards; triangles were reversed
    std::int64_t droppedDegenerate = 0;  // triangles with a repeated vertex, removed
    double volume() const;             // enclosed volume (divergence theorem)
    double area() const;
};

// Reads, welds vertices at identical positions, and checks that the surface
// is closed, edge-manifold and consistently oriented; a surface oriented
// inwards is flipped (and `flipped` set). Throws isohex::Error otherwise.
TriangleSurface loadSurface(const std::filesystem::path& path);
// The same checks on a surface built in memory.
void checkClosedManifold(TriangleSurface& surface);

// Connected components (triangles joined through shared vertices) and Euler
// characteristic V - E + F of the triangles (2 - 2g per closed component of
// genus g): what the mesh's boundary should have, whatever the element size.
struct SurfaceTopology {
    std::size_t components = 0;
    long long euler = 0;
};
SurfaceTopology surfaceTopology(const TriangleSurface& surface);

struct LevelSetOptions {
    double elementSize = 1.0;       // the intended hex edge length, world units
    double voxelsPerElement = 2.0;  // voxel size = elementSize / voxelsPerElement
    double halfWidthVoxels = 3.0;   // narrow band each side of the surface
    // Store true distances in the whole interior (costs memory ~ volume).
    bool fillInterior = false;
    double maxMemoryMB = 0.0;       // 0 = 80 % of physical memory
    Interpolation interpolation = Interpolation::Trilinear;
};

struct SurfaceLevelSet {
    openvdb::FloatGrid::Ptr grid;  // GRID_LEVEL_SET, uniform voxels, negative inside
    double voxelSize = 0.0;
    ImplicitField field;
    TriangleSurface surface;       // the triangles are kept for exact queries later
};

SurfaceLevelSet surfaceToLevelSet(TriangleSurface surface, const LevelSetOptions& options = {});

}  // namespace isohex::imaging
